"""An obstacle-blind 'planner' for the "PPO Lag + SAC" ablation (thesis Table 3.1, App. B).

The high level's subgoal goes straight to the follower: the plan is the straight segment from
the root to the subgoal, sampled at ``n_waypoints`` points, whatever the obstacles. Its
certificate fields report the actual clearance, so logs show what the planner would have
prevented.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass
class StraightPlan:
    """Result of :meth:`StraightLinePlanner.plan` (the fields the SEMDP wrapper reads)."""

    waypoints: np.ndarray
    feasible: bool
    fallback: bool
    escape_mode: bool
    min_clearance: float
    solve_time_s: float
    reached_subgoal: bool = True
    backend: str = "straight"


class StraightLinePlanner:
    """Straight line from start to subgoal (no obstacle avoidance).

    Args:
        n_waypoints: points on the segment, the start included (thesis plans: 30).
        clearance: only used to fill ``feasible`` (every waypoint >= clearance + r away).
    """

    def __init__(self, n_waypoints: int = 30, clearance: float = 0.5) -> None:
        if n_waypoints < 2:
            raise ValueError(f"n_waypoints must be >= 2, got {n_waypoints}")
        self.n_waypoints = int(n_waypoints)
        self.clearance = float(clearance)

    def plan(self, start, subgoal, obstacles=None, warm_start: bool = True) -> StraightPlan:
        """The segment start -> subgoal; ``warm_start`` is accepted and ignored."""
        tic = time.perf_counter()
        start = np.asarray(start, dtype=np.float64).reshape(2)
        subgoal = np.asarray(subgoal, dtype=np.float64).reshape(2)
        t = np.linspace(0.0, 1.0, self.n_waypoints)[:, None]
        waypoints = start + t * (subgoal - start)
        clearance = np.inf
        obstacles = np.zeros((0, 3)) if obstacles is None else np.asarray(obstacles, float)
        if len(obstacles):
            obstacles = obstacles.reshape(len(obstacles), -1)
            radii = obstacles[:, 2] if obstacles.shape[1] > 2 else np.zeros(len(obstacles))
            gaps = np.linalg.norm(waypoints[:, None] - obstacles[None, :, :2], axis=-1) - radii
            clearance = float(gaps.min())
        return StraightPlan(
            waypoints=waypoints,
            feasible=bool(clearance >= self.clearance),
            fallback=False,
            escape_mode=False,
            min_clearance=clearance,
            solve_time_s=time.perf_counter() - tic,
        )
