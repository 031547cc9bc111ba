"""Obstacle positions from pseudo-LiDAR bins: the thesis' default perception (§3.6.3).

A bin ``i`` with reading ``s > 0`` says "an object at distance ``(1 − s) · max_dist`` somewhere
in the bin's 22.5° sector". The reconstruction puts it at the bin-centre bearing
``(i + 0.5) · 2π/16`` in the robot's body frame. Errors (Safety-Gymnasium 1.0.0's algorithm):

* distance: exact for the bin that holds the object (its reading is ``(3 − d)/3``); aliased
  neighbours read ``α·s`` or ``(1 − α)·s`` and so place ghosts *farther* away;
* bearing: up to half a bin (11.25°), i.e. a lateral error up to ``d · sin(11.25°) ≈ 0.195 d``
  (0.39 m at 2 m);
* merging: objects in the same bin collapse onto the nearest; size and occlusion are ignored.

``peaks_only=True`` (default) keeps local maxima only, which removes the aliasing ghosts of an
isolated object; ``refine_bearing=True`` recovers the exact bearing of an isolated object from
the aliasing ratio (an improvement over the thesis, off by default).
"""

from __future__ import annotations

import math

import numpy as np

BINS = 16


def obstacles_from_lidar(
    lidar: np.ndarray,
    robot_position: np.ndarray,
    robot_heading: float,
    max_dist: float = 3.0,
    min_reading: float = 1e-6,
    peaks_only: bool = True,
    refine_bearing: bool = False,
) -> np.ndarray:
    """Reconstruct world positions ``(k, 2)`` of objects from one 16-bin LiDAR channel.

    Args:
        lidar: the channel, shape ``(16,)``, readings in [0, 1] (e.g. ``obs[env.obs_slices
            ["hazards_lidar"]]``).
        robot_position: robot root ``(x, y)`` in the world.
        robot_heading: body yaw in rad (``env.robot_heading``: bin 0 starts at body +x).
        max_dist: LiDAR range (3 m in Safety Gym).
        min_reading: bins at or below this reading are empty.
        peaks_only: keep only bins that are local maxima (circularly), dropping aliasing ghosts.
        refine_bearing: place a peak at the bearing implied by its neighbours' aliasing instead
            of the bin centre.

    Returns:
        Array ``(k, 2)`` of estimated object centres, in bin order.

    Raises:
        ValueError: for a wrong shape, non-finite values or readings outside [0, 1].
    """
    lidar = np.asarray(lidar, dtype=np.float64)
    if lidar.shape != (BINS,):
        raise ValueError(f"lidar must have shape ({BINS},), got {lidar.shape}")
    if not np.isfinite(lidar).all() or lidar.min() < 0.0 or lidar.max() > 1.0:
        raise ValueError(f"lidar readings must be finite and in [0, 1], got {lidar}")
    position = np.asarray(robot_position, dtype=np.float64).reshape(2)
    if not np.isfinite(position).all() or not math.isfinite(robot_heading):
        raise ValueError("robot_position and robot_heading must be finite")
    if not max_dist > 0:
        raise ValueError(f"max_dist must be positive, got {max_dist}")
    width = 2.0 * math.pi / BINS
    points = []
    values = lidar.tolist()
    for i, s in enumerate(values):
        if s <= min_reading:
            continue
        left, right = values[(i - 1) % BINS], values[(i + 1) % BINS]
        if peaks_only and not (s > left and s >= right):
            continue
        bearing = (i + 0.5) * width
        if refine_bearing and s > 0.0:
            # aliasing: right = alpha * s and left = (1 - alpha) * s for an isolated object
            alpha = right / s if right > 0.0 else 1.0 - left / s
            bearing = (i + min(max(alpha, 0.0), 1.0)) * width
        dist = (1.0 - s) * max_dist
        angle = robot_heading + bearing
        points.append((position[0] + dist * math.cos(angle), position[1] + dist * math.sin(angle)))
    return np.array(points, dtype=np.float64).reshape(-1, 2)
