"""Safety Gym's 16-bin pseudo-LiDAR in plain Python math (Safety-Gymnasium 1.0.0).

The reading of an object at egocentric distance ``d`` is ``max(0, 3 - d) / 3`` in the bin that
contains its bearing; with aliasing, the two neighbouring bins get ``alpha * s`` and
``(1 - alpha) * s``. Object size and occlusion are ignored, as in Safety-Gymnasium. Plain Python
on a preallocated list: numpy calls on 16-element arrays cost more than the arithmetic itself.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from sims.safety_gym.config import LIDAR_BINS, LIDAR_MAX_DIST

_TWO_PI = 2.0 * math.pi
_INV_BIN = LIDAR_BINS / _TWO_PI
_MASK = LIDAR_BINS - 1
_INV_MAX = 1.0 / LIDAR_MAX_DIST


def fill_pseudo_lidar(
    out: list[float],
    offset: int,
    points: Iterable[Sequence[float]],
    robot_x: float,
    robot_y: float,
    cos_yaw: float,
    sin_yaw: float,
) -> None:
    """Write one object type's 16 readings into ``out[offset:offset + 16]`` (max-combined).

    Args:
        out: the flat observation as a Python list; the 16 slots must already be zeroed.
        offset: index of bin 0 in ``out``.
        points: object centres ``(x, y)`` in world coordinates (metres).
        robot_x, robot_y: the robot root in world coordinates.
        cos_yaw, sin_yaw: cosine and sine of the body yaw; bin 0 starts at body +x and bins
            run counter-clockwise.
    """
    for px, py in points:
        dx = px - robot_x
        dy = py - robot_y
        ex = cos_yaw * dx + sin_yaw * dy
        ey = cos_yaw * dy - sin_yaw * dx
        dist = math.sqrt(ex * ex + ey * ey)
        if dist >= LIDAR_MAX_DIST:
            continue
        angle = math.atan2(ey, ex)
        if angle < 0.0:
            angle += _TWO_PI
        z = angle * _INV_BIN
        i = int(z)
        if i >= LIDAR_BINS:  # angle rounded up to exactly 2*pi
            i, z = 0, 0.0
        alpha = z - i
        s = (LIDAR_MAX_DIST - dist) * _INV_MAX
        k = offset + i
        if s > out[k]:
            out[k] = s
        k = offset + ((i + 1) & _MASK)
        v = alpha * s
        if v > out[k]:
            out[k] = v
        k = offset + ((i - 1) & _MASK)
        v = (1.0 - alpha) * s
        if v > out[k]:
            out[k] = v
