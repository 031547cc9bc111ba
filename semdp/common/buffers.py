"""Rollout storage of the on-policy algorithms (the replay buffer of SAC:
:mod:`semdp.algos.replay_shared`)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch

from semdp.common.advantages import gae


class RolloutBatch(NamedTuple):
    """A flattened on-policy batch; every field has leading size ``n_steps * n_envs``."""

    obs: torch.Tensor
    actions: torch.Tensor
    log_probs: torch.Tensor
    adv_r: torch.Tensor
    adv_c: torch.Tensor
    ret_r: torch.Tensor
    ret_c: torch.Tensor


class RolloutBuffer:
    """Fixed-size rollout storage with shape ``(n_steps, n_envs, ...)``.

    ``next_values_*`` hold the already-resolved bootstrap of each step (see
    :mod:`semdp.common.advantages`).
    """

    FIELDS = (
        "rewards", "costs", "values_r", "values_c", "next_values_r", "next_values_c",
        "terminated", "episode_end", "log_probs",
    )

    def __init__(self, n_steps: int, n_envs: int, obs_dim: int, act_dim: int) -> None:
        if n_steps < 1 or n_envs < 1:
            raise ValueError(f"n_steps and n_envs must be >= 1, got {n_steps}, {n_envs}")
        self.n_steps, self.n_envs = n_steps, n_envs
        self.obs = np.zeros((n_steps, n_envs, obs_dim), dtype=np.float32)
        self.actions = np.zeros((n_steps, n_envs, act_dim), dtype=np.float32)
        for name in self.FIELDS:
            setattr(self, name, np.zeros((n_steps, n_envs), dtype=np.float64))
        self.pos = 0

    def add(self, **row: Any) -> None:
        """Store one vector step; keys are ``obs``, ``actions`` and :attr:`FIELDS`."""
        if self.pos >= self.n_steps:
            raise RuntimeError("rollout buffer is full; call reset() after compute()")
        for name, value in row.items():
            getattr(self, name)[self.pos] = value
        self.pos += 1

    def reset(self) -> None:
        """Start a new rollout."""
        self.pos = 0

    def compute(
        self, gamma: float, gae_lambda: float, gamma_c: float, gae_lambda_c: float
    ) -> RolloutBatch:
        """GAE for reward and cost; A_r standardised, A_c only centred (OmniSafe/safety-starter)."""
        if self.pos != self.n_steps:
            raise RuntimeError(f"rollout incomplete: {self.pos}/{self.n_steps} steps")
        adv_r, ret_r = gae(
            self.rewards, self.values_r, self.next_values_r, self.terminated,
            self.episode_end, gamma, gae_lambda,
        )
        adv_c, ret_c = gae(
            self.costs, self.values_c, self.next_values_c, self.terminated,
            self.episode_end, gamma_c, gae_lambda_c,
        )
        adv_r = (adv_r - adv_r.mean()) / (adv_r.std() + 1e-8)
        adv_c = adv_c - adv_c.mean()

        def flat(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(x.reshape(self.n_steps * self.n_envs, *x.shape[2:])).float()

        return RolloutBatch(
            obs=flat(self.obs), actions=flat(self.actions), log_probs=flat(self.log_probs),
            adv_r=flat(adv_r), adv_c=flat(adv_c), ret_r=flat(ret_r), ret_c=flat(ret_c),
        )
