"""Generalised advantage estimation for reward and cost (Schulman et al. 2016).

Time-out convention: a time-out (truncation) is bootstrapped with the value of the true final
observation, a termination is not. Callers pass, for every step, the value of the *next* state
already resolved: ``V(s_{t+1})`` after an ordinary step or a time-out, and anything (masked by
``terminated``) after a termination. ``episode_end`` cuts the recursion at both kinds of end.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

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
