"""The tests' way to put a :class:`~semdp.embedded.shield.SafetyShield` on a bare Safety Gym
replica env (the Safety-Embedded MDP applies it itself: ``SafetyEmbeddedEnv(..., shield=...)``)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from semdp.embedded.shield import SafetyShield


class ShieldedEnv(gym.Wrapper):
    """Applies a :class:`SafetyShield` to every action of a Safety Gym replica env;
    ``info["shield_replaced"]`` says whether this step's command was replaced."""

    def __init__(self, env: gym.Env, shield: SafetyShield) -> None:
        super().__init__(env)
        self.shield = shield
        self._obs: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset and bind the filter to the new episode's objects."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.shield.bind(self.env.unwrapped)
        self.shield.new_episode()
        self._obs = obs
        return obs, info

    def step(self, action: Any):
        """Filter ``action``, then step."""
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        safe = self.shield.filter(np.asarray(action), self.env.unwrapped, self._obs)
        obs, reward, terminated, truncated, info = self.env.step(safe)
        self._obs = obs
        info["shield_replaced"] = safe is not action and not np.array_equal(safe, action)
        return obs, reward, terminated, truncated, info
