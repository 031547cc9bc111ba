"""A tiny constrained MDP for tests and learning checks: ``semdp/SpeedLimit-v0``.

## Description
A cart on a straight road chooses its acceleration. Reward is the speed reached, so faster is
better; the cost is Safety-Gym style, an indicator of speeding: ``1[v > speed_limit]``. Driving
at or above ``crash_speed`` ends the episode (a termination, not a time-out), so an
unconstrained agent hovers just below the crash speed and speeds on almost every step, while a
constrained agent must ration the steps it spends above the speed limit.

## Action Space
``Box(-1, 1, (1,))``: acceleration command; ``v <- clip(v + accel_gain * a, -crash, crash)``.

## Observation Space
``[v, t / max_episode_steps]`` (float32), so the policy can spend its cost budget late.

## Rewards / Costs
``r_t = v_{t+1}``; ``info["cost"] = info["cost_speeding"] = 1.0 if v_{t+1} > speed_limit``.

## Episode Termination
Terminated when ``v >= crash_speed``; truncated after ``max_episode_steps`` (100, TimeLimit).

>>> import gymnasium as gym, sims
>>> env = gym.make("semdp/SpeedLimit-v0")
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

ENV_ID = "semdp/SpeedLimit-v0"
MAX_EPISODE_STEPS = 100


class SpeedLimitEnv(gym.Env):
    """Speed-vs-speeding CMDP (see the module docstring).

    Args:
        speed_limit: speeds above this cost 1 per step.
        crash_speed: speeds at or above this terminate the episode.
        accel_gain: change of speed per unit action.
        max_episode_steps: horizon used for the time feature (the TimeLimit is set at
            registration with the same value).
    """

    metadata = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        speed_limit: float = 1.0,
        crash_speed: float = 2.0,
        accel_gain: float = 0.2,
        max_episode_steps: int = MAX_EPISODE_STEPS,
    ) -> None:
        if not 0 < speed_limit < crash_speed:
            raise ValueError(
                f"need 0 < speed_limit < crash_speed, got {speed_limit} and {crash_speed}"
            )
        if accel_gain <= 0 or max_episode_steps < 1:
            raise ValueError(
                f"accel_gain must be > 0 and max_episode_steps >= 1, got {accel_gain}, "
                f"{max_episode_steps}"
            )
        self.speed_limit, self.crash_speed = speed_limit, crash_speed
        self.accel_gain, self.horizon = accel_gain, max_episode_steps
        self.action_space = gym.spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (2,), dtype=np.float32)
        self._v, self._t = 0.0, 0

    def _obs(self) -> np.ndarray:
        return np.array([self._v, self._t / self.horizon], dtype=np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start at a small random speed."""
        super().reset(seed=seed)
        self._v, self._t = float(self.np_random.uniform(0.0, 0.2)), 0
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Accelerate, collect the speed as reward and the speeding indicator as cost."""
        a = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[0], -1.0, 1.0))
        self._v = float(np.clip(self._v + self.accel_gain * a, -self.crash_speed,
                                self.crash_speed))
        self._t += 1
        cost = float(self._v > self.speed_limit)
        terminated = self._v >= self.crash_speed
        info = {"cost": cost, "cost_speeding": cost}
        return self._obs(), self._v, terminated, False, info


if ENV_ID not in gym.registry:
    gym.register(
        id=ENV_ID,
        entry_point="sims.testbed:SpeedLimitEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )
