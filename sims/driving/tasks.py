"""The two driving tasks of thesis App. A.2 (Fig. A.2): the track each follows and where its
episodes start, over the MDP of :mod:`sims.driving.base` (observation, reward Eq. A.1, cost
Eq. A.2).

Registered as ``sims/DriveCircle-v0`` and ``sims/DriveTrajectory-v0`` by :mod:`sims.driving`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sims.driving.base import DrivingEnv
from sims.driving.tracks import CircleTrack, RandomPathTrack


class DriveCircleEnv(DrivingEnv):
    """``sims/DriveCircle-v0``: follow a counter-clockwise circle (App. A.2, Fig. A.2 left).

    Args:
        radius: Circle radius [m] (default 1 m, as aa_simulation's CircleEnv).
        **kwargs: See :class:`DrivingEnv`.
    """

    def __init__(self, radius: float = 1.0, **kwargs: Any) -> None:
        self.radius = float(radius)
        super().__init__(**kwargs)

    def _make_track(self) -> CircleTrack:
        return CircleTrack(self.radius)

    def _start_arc_length(self) -> float:
        return float(self.np_random.uniform(0.0, 2.0 * math.pi * self.radius))


class DriveTrajectoryEnv(DrivingEnv):
    """``sims/DriveTrajectory-v0``: follow a seeded random smooth path (App. A.2, Fig. A.2 right).

    A new path (:class:`RandomPathTrack`) is drawn from the env's generator at every reset; its
    length covers ``episode_length * dt`` at 10.5 m/s (above the top speed) plus the preview.

    Args:
        preview_points: K, number of centre-line points in the observation.
        preview_spacing: Arc-length spacing of those points [m] (multiple of 0.05 m).
        max_curvature: Largest path curvature [1/m] (tightest turn radius 1.5 m by default).
        max_heading: Largest heading deviation of the path from +x [rad].
        **kwargs: See :class:`DrivingEnv`.
    """

    SPACING = 0.05
    START_ARC_LENGTH = 2.0

    def __init__(
        self,
        preview_points: int = 10,
        preview_spacing: float = 0.4,
        max_curvature: float = 1.0 / 1.5,
        max_heading: float = 1.0,
        **kwargs: Any,
    ) -> None:
        if int(preview_points) != preview_points or not 1 <= preview_points <= 50:
            raise ValueError(f"preview_points must be an integer in [1, 50], "
                             f"got {preview_points!r}")
        stride = round(preview_spacing / self.SPACING)
        if stride < 1 or abs(stride * self.SPACING - preview_spacing) > 1e-9:
            raise ValueError(f"preview_spacing must be a positive multiple of {self.SPACING} m, "
                             f"got {preview_spacing!r}")
        self.preview_points = int(preview_points)
        self.preview_spacing = float(preview_spacing)
        self._stride = int(stride)
        self.max_curvature = float(max_curvature)
        self.max_heading = float(max_heading)
        self._path_length = 0.0
        super().__init__(**kwargs)

    def _make_track(self) -> RandomPathTrack:
        self._path_length = (10.5 * self.episode_length * self.dt + self.START_ARC_LENGTH
                             + self.preview_points * self.preview_spacing + 2.0)
        return self._draw_track(np.random.default_rng(0))

    def _draw_track(self, rng: np.random.Generator) -> RandomPathTrack:
        return RandomPathTrack(rng, length=self._path_length, spacing=self.SPACING,
                               max_heading=self.max_heading, max_curvature=self.max_curvature)

    def _new_episode_track(self, rng: np.random.Generator) -> None:
        self.track = self._draw_track(rng)

    def _start_arc_length(self) -> float:
        return self.START_ARC_LENGTH

    def _path_ended(self) -> bool:
        return self._hint + self.preview_points * self._stride >= self.track.last_index

    def _extra_bounds(self) -> tuple[list[float], list[float]]:
        bound = self.preview_points * self.preview_spacing + self.d_bound + 1.0
        return [-bound] * (2 * self.preview_points), [bound] * (2 * self.preview_points)

    def _extra_observation(self, x: float, y: float, psi: float) -> list[float]:
        track = self.track
        xs, ys = track.xs, track.ys
        c = math.cos(psi)
        s = math.sin(psi)
        last = track.last_index
        out: list[float] = []
        index = self._hint
        for _ in range(self.preview_points):
            index += self._stride
            i = index if index < last else last
            dx = xs[i] - x
            dy = ys[i] - y
            out.append(c * dx + s * dy)
            out.append(c * dy - s * dx)
        return out
