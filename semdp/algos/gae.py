"""Rollout storage and generalised advantage estimation for reward and cost (Schulman et al.
2016; the constrained variant's two critics, thesis Eqs. 2.4-2.7).

Time-out convention: a time-out (truncation) is bootstrapped with the value of the true final
observation, a termination is not. :func:`gae` takes, for every step, the value of the *next*
state already resolved: ``V(s_{t+1})`` after an ordinary step or a time-out, and anything
(masked by ``terminated``) after a termination. ``episode_end`` cuts the recursion at both kinds
of end. (The replay buffer of SAC: :mod:`semdp.algos.sac.replay`.)
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import torch

FloatArray = npt.NDArray[np.float64]


def gae(
    rewards: npt.ArrayLike,
    values: npt.ArrayLike,
    next_values: npt.ArrayLike,
    terminated: npt.ArrayLike,
    episode_end: npt.ArrayLike,
    gamma: float,
    gae_lambda: float,
) -> tuple[FloatArray, FloatArray]:
    """Advantages and value targets along the leading (time) axis.

    ``delta_t = r_t + gamma * (1 - terminated_t) * V(s_{t+1}) - V(s_t)`` and
    ``A_t = delta_t + gamma * lambda * (1 - episode_end_t) * A_{t+1}``; the last row is treated as
    cut (its bootstrap lives in ``next_values``). Works for reward and cost alike.

    Args:
        rewards: per-step rewards (or costs), shape ``(n_steps, ...)``.
        values: ``V(s_t)``, same shape.
        next_values: ``V(s_{t+1})`` with ``s_{t+1}`` the true next/final observation.
        terminated: 1 where the episode terminated (no bootstrap).
        episode_end: 1 where the episode ended by termination or time-out.
        gamma: discount in [0, 1].
        gae_lambda: GAE lambda in [0, 1].

    Returns:
        ``(advantages, returns)`` with ``returns = advantages + values``.
    """
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma}")
    if not 0.0 <= gae_lambda <= 1.0:
        raise ValueError(f"gae_lambda must be in [0, 1], got {gae_lambda}")
    r = np.asarray(rewards, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    nv = np.asarray(next_values, dtype=np.float64)
    term = np.asarray(terminated, dtype=np.float64)
    end = np.asarray(episode_end, dtype=np.float64)
    if not (r.shape == v.shape == nv.shape == term.shape == end.shape):
        raise ValueError(
            f"shapes differ: rewards {r.shape}, values {v.shape}, next_values {nv.shape}, "
            f"terminated {term.shape}, episode_end {end.shape}"
        )
    deltas = r + gamma * (1.0 - term) * nv - v
    adv = np.zeros_like(r)
    running = np.zeros_like(r[0]) if r.ndim else 0.0
    for t in reversed(range(r.shape[0])):
        continuing = 0.0 if t == r.shape[0] - 1 else 1.0 - end[t]
        running = deltas[t] + gamma * gae_lambda * continuing * running
        adv[t] = running
    return adv, adv + v


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
    :func:`gae`).
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
