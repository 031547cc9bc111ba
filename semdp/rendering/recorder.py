"""A wrapper that records annotated frames of the env it wraps, every ``every`` steps.

Put it innermost (directly around the simulator), so that it sees every low-level step and its
cost, also under a Safety-Embedded MDP wrapper, which steps the simulator ``k`` times per action.
Whoever drives the episode sets :attr:`FrameRecorder.perceived` and
:attr:`FrameRecorder.clearance` before each planning step (``semdp.evaluation.episodes``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from semdp.rendering.overlay import FrameNotes, annotate


class FrameRecorder(gym.Wrapper):
    """Appends an annotated ``render()`` frame to :attr:`frames` after the reset and every
    ``every`` steps (and on the episode's last step) while :attr:`active`.

    Args:
        env: an env made with ``render_mode="rgb_array"``.
        every: record a frame every this many steps.
    """

    def __init__(self, env: gym.Env, every: int = 1) -> None:
        super().__init__(env)
        if every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.every = int(every)
        self.active = False
        self.frames: list[np.ndarray] = []
        self.perceived: np.ndarray | None = None
        self.clearance: float | None = None
        self._step = 0
        self._return = self._cost = 0.0
        self._cost_since_frame = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset; the first frame of an active recording."""
        out = self.env.reset(seed=seed, options=options)
        self._step, self._return, self._cost = 0, 0.0, 0.0
        self._cost_since_frame = False
        self.perceived = None
        if self.active:
            self._capture()
        return out

    def step(self, action: Any):
        """Step; a frame every ``every`` steps and at the episode's end."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        cost = float(info.get("cost", 0.0))
        self._step += 1
        self._return += float(reward)
        self._cost += cost
        self._cost_since_frame = self._cost_since_frame or cost > 0
        if self.active and (self._step % self.every == 0 or terminated or truncated):
            self._capture()
        return obs, reward, terminated, truncated, info

    def _capture(self) -> None:
        frame = self.env.render()
        if frame is None:
            raise RuntimeError("the env rendered no frame: make it with render_mode='rgb_array'")
        notes = FrameNotes(self._step, self._return, self._cost, self._cost_since_frame,
                           self.perceived, self.clearance)
        self.frames.append(annotate(np.asarray(frame), self.env.unwrapped, notes))
        self._cost_since_frame = False
