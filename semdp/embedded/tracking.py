"""Tracking-point selection of the trajectory-following module (thesis App. B.2.2)."""

from __future__ import annotations

import math

import numpy as np


def select_tracking_index(
    waypoints: np.ndarray, robot_position: np.ndarray, last_index: int, d_min: float
) -> int:
    """Return the index of the waypoint the follower should chase now (App. B.2.2).

    Starting from the previously tracked index, search towards the end of the trajectory for the
    first waypoint at least ``d_min`` away from the robot root. If none is that far, the last
    waypoint is tracked. The index never moves backwards, so the follower makes progress along
    the plan even when the path doubles back near the robot.

    Args:
        waypoints: (N, 2) planned waypoints.
        robot_position: (2,) current root position.
        last_index: the tracking index of the previous low-level step (0 after a new plan).
        d_min: the minimum look-ahead distance (0.2 m in the thesis).
    """
    n = len(waypoints)
    if n == 0:
        raise ValueError("waypoints must hold at least one point")
    if d_min < 0:
        raise ValueError(f"d_min must be >= 0, got {d_min}")
    px, py = float(robot_position[0]), float(robot_position[1])
    for i in range(max(0, min(last_index, n - 1)), n):
        if math.hypot(waypoints[i, 0] - px, waypoints[i, 1] - py) >= d_min:
            return i
    return n - 1


def world_to_ego(vector: np.ndarray, heading: float) -> np.ndarray:
    """Rotate a world-frame 2D vector into the robot frame (x forward, y left)."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([c * vector[0] + s * vector[1], -s * vector[0] + c * vector[1]])


def ego_to_world(vector: np.ndarray, heading: float) -> np.ndarray:
    """Rotate a robot-frame 2D vector into the world frame (inverse of :func:`world_to_ego`)."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])
