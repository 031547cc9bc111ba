"""n-step returns for SAC's replay rows (Sutton & Barto 2018, §7.1; the multi-step targets of
Rainbow and of SAC variants for small data).

:class:`NStepReturns` sits between a vector env and the replay buffer: it keeps each env's last
``n`` one-step transitions and emits a row ``(s_t, a_t, R, c, s_{t+m}, terminated, m)`` with
``R = sum_{l<m} gamma^l r_{t+l}`` (the costs summed the same way) once ``m = n`` steps have
followed ``s_t``, or, when the episode ends earlier, one row for every pending step with the
``m`` steps left to the end. The critic's target is then
``R + gamma^m (1 - terminated) V(s_{t+m})`` (:class:`~semdp.algos.sac.learner.SACLearner`):
a time-out still bootstraps, now ``m`` steps ahead.

With ``n = 1`` a row is the one-step transition itself; SAC then stores its transitions directly
and never builds this class.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

#: One pending step of one env: (obs, action, reward, cost).
_Step = tuple[np.ndarray, np.ndarray, float, float]


class NStepReturns:
    """Per-env windows of the last ``n`` steps, emitted as n-step replay rows.

    Args:
        n: steps summed per row (>= 1).
        gamma: discount of the summed rewards and costs.
        num_envs: environments of the vector env.
    """

    def __init__(self, n: int, gamma: float, num_envs: int) -> None:
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.n, self.gamma, self.num_envs = int(n), float(gamma), int(num_envs)
        self.pending: list[deque[_Step]] = [deque() for _ in range(num_envs)]

    def push(
        self,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        costs: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        ended: np.ndarray,
    ) -> tuple[np.ndarray, ...]:
        """Add one vector step; return the rows it completes, env by env, oldest first:
        ``(obs, actions, rewards, costs, next_obs, terminated, horizons)``, float32 arrays with
        a leading axis of 0 or more rows.

        Args:
            obs, actions: the step's observations and actions (leading axis: env).
            rewards, costs: its one-step rewards and costs.
            next_obs: the observation after the step (the final one where an episode ended).
            terminated: 1 where the step reached a terminal state.
            ended: where the episode ended (terminated or truncated).
        """
        rows: list[tuple[np.ndarray, np.ndarray, float, float, np.ndarray, float, int]] = []
        for i in range(self.num_envs):
            window = self.pending[i]
            window.append((obs[i], actions[i], float(rewards[i]), float(costs[i])))
            if ended[i]:
                while window:
                    rows.append(self._row(window, next_obs[i], float(terminated[i])))
                    window.popleft()
            elif len(window) == self.n:
                rows.append(self._row(window, next_obs[i], 0.0))
                window.popleft()
        return self._stack(rows, obs, actions)

    def _row(self, window: deque[_Step], next_obs: np.ndarray, terminated: float
             ) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray, float, int]:
        """The row of the window's oldest step, bootstrapping from ``next_obs``."""
        reward = cost = 0.0
        for k, (_, _, r, c) in enumerate(window):
            reward += self.gamma ** k * r
            cost += self.gamma ** k * c
        first_obs, first_action = window[0][0], window[0][1]
        return first_obs, first_action, reward, cost, next_obs, terminated, len(window)

    @staticmethod
    def _stack(rows: list[Any], obs: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, ...]:
        if not rows:
            return (np.zeros((0, *obs.shape[1:]), np.float32),
                    np.zeros((0, *actions.shape[1:]), np.float32),
                    *(np.zeros((0,), np.float32) for _ in range(2)),
                    np.zeros((0, *obs.shape[1:]), np.float32),
                    *(np.zeros((0,), np.float32) for _ in range(2)))
        columns = list(zip(*rows, strict=True))
        return tuple(np.asarray(np.stack(col) if isinstance(col[0], np.ndarray) else col,
                                dtype=np.float32) for col in columns)

    def state_dict(self) -> dict[str, Any]:
        """The pending steps of every env (so that a resumed run emits the same rows)."""
        return {"n": self.n, "pending": [[tuple(np.copy(x) if isinstance(x, np.ndarray) else x
                                                for x in step) for step in window]
                                         for window in self.pending]}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        if int(state["n"]) != self.n:
            raise ValueError(f"checkpoint has n-step windows of {state['n']}, this run {self.n}")
        self.pending = [deque(tuple(step) for step in window) for window in state["pending"]]

    def clear(self) -> None:
        """Drop the pending steps (the episodes in progress were restarted)."""
        for window in self.pending:
            window.clear()
