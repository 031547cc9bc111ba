"""Rollout (on-policy) and replay (off-policy) storage."""

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


class ReplayBatch(NamedTuple):
    """A sampled off-policy batch."""

    obs: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor
    costs: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor


class ReplayBuffer:
    """Circular replay buffer of raw transitions; sampling uses torch's global generator."""

    def __init__(self, capacity: int, obs_dim: int, act_dim: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self.obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.next_obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.actions = np.zeros((capacity, act_dim), dtype=np.float32)
        self.rewards = np.zeros(capacity, dtype=np.float32)
        self.costs = np.zeros(capacity, dtype=np.float32)
        self.terminated = np.zeros(capacity, dtype=np.float32)
        self.pos, self.size = 0, 0

    def add_batch(
        self,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        costs: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
    ) -> None:
        """Store ``n`` transitions (leading axis = env index)."""
        for i in range(len(rewards)):
            p = self.pos
            self.obs[p], self.actions[p], self.next_obs[p] = obs[i], actions[i], next_obs[i]
            self.rewards[p], self.costs[p], self.terminated[p] = rewards[i], costs[i], terminated[i]
            self.pos = (p + 1) % self.capacity
            self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int) -> ReplayBatch:
        """Uniform sample with replacement."""
        if self.size == 0:
            raise RuntimeError("cannot sample from an empty replay buffer")
        idx = torch.randint(0, self.size, (batch_size,)).numpy()
        t = torch.as_tensor
        return ReplayBatch(
            t(self.obs[idx]), t(self.actions[idx]), t(self.rewards[idx]), t(self.costs[idx]),
            t(self.next_obs[idx]), t(self.terminated[idx]),
        )

    def state_dict(self) -> dict[str, Any]:
        """Filled part of the storage and the write position."""
        n = self.size
        return {
            "pos": self.pos, "size": n, "obs": self.obs[:n].copy(),
            "next_obs": self.next_obs[:n].copy(), "actions": self.actions[:n].copy(),
            "rewards": self.rewards[:n].copy(), "costs": self.costs[:n].copy(),
            "terminated": self.terminated[:n].copy(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        n = state["size"]
        for name in ("obs", "next_obs", "actions", "rewards", "costs", "terminated"):
            getattr(self, name)[:n] = state[name]
        self.pos, self.size = state["pos"], n
