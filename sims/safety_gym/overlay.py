"""Rendering of a Safety Gym env: ``render()`` frames with an optional planned-path overlay.

The Safety-Embedded MDP draws its plan and subgoal on evaluation frames (thesis §3.5);
:meth:`TopDownRendering.set_overlay` keeps them until they are replaced or cleared, and
:meth:`TopDownRendering.render` hands them to :func:`~sims.safety_gym.render.render_topdown`.
"""

from __future__ import annotations

from typing import cast

import numpy as np
import pymunk

from sims.safety_gym.render import TopDownScene, render_topdown


class TopDownRendering:
    """Mixin of :class:`~sims.safety_gym.env.SafetyGymEnv`: ``rgb_array`` frames and overlay."""

    render_mode: str | None
    render_size: int
    space: pymunk.Space | None
    _overlay_waypoints: np.ndarray | None = None
    _overlay_subgoal: np.ndarray | None = None

    def set_overlay(
        self, waypoints: np.ndarray | None = None, subgoal: np.ndarray | None = None
    ) -> None:
        """Draw a planned path ``(n, 2)`` and/or a subgoal ``(2,)`` on subsequent frames.

        ``None`` clears that part of the overlay.
        """
        if waypoints is not None:
            waypoints = np.asarray(waypoints, dtype=np.float64).reshape(-1, 2)
        if subgoal is not None:
            subgoal = np.asarray(subgoal, dtype=np.float64).reshape(2)
        self._overlay_waypoints, self._overlay_subgoal = waypoints, subgoal

    def render(self) -> np.ndarray | None:
        """Top-down ``(H, W, 3)`` uint8 frame when ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            return None
        if self.space is None:
            raise RuntimeError("call reset() before render()")
        scene = cast(TopDownScene, self)  # the env has every attribute the drawing reads
        return render_topdown(
            scene, self.render_size, self._overlay_waypoints, self._overlay_subgoal
        )
