"""An obstacle-blind 'planner' for the "PPO Lag + SAC" ablation (thesis Table 3.1, App. B).

The high level's subgoal goes straight to the follower: the plan is the straight segment from
the root to the subgoal, sampled at ``n_waypoints`` points, whatever the obstacles. It satisfies
the :class:`~solvers.planner.Planner` protocol and returns a :class:`~solvers.planner.PlanResult`
whose certificate fields report the actual clearance, so logs show what the planner would have
prevented.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from solvers.planner import PlanResult, ProblemSettings
from solvers.planner.geometry import point_distances, segment_distances

#: ``PlanResult.backend`` and ``status`` of a straight-line plan.
STRAIGHT = "straight"


class StraightLinePlanner:
    """Straight line from start to subgoal (no obstacle avoidance).

    Args:
        n_waypoints: points on the segment, the start included (default: the planning
            problem's, :class:`~solvers.planner.ProblemSettings`).
        clearance: only used to fill ``feasible`` (every waypoint >= clearance + r away;
            default: the planning problem's eps').
        rescue_backend: must be None; accepted so that every ``conf/planner`` entry shares the
            key (the optimising planners take ``"ipopt"`` there).

    Raises:
        ValueError: ``n_waypoints < 2`` or a ``rescue_backend``.
    """

    def __init__(
        self, n_waypoints: int = ProblemSettings.n_waypoints,
        clearance: float = ProblemSettings.clearance, rescue_backend: str | None = None,
    ) -> None:
        if n_waypoints < 2:
            raise ValueError(f"n_waypoints must be >= 2, got {n_waypoints}")
        if rescue_backend is not None:
            raise ValueError(
                "the straight-line ablation planner has no rescue: rescue_backend must be None, "
                f"got {rescue_backend!r}"
            )
        self.n_waypoints = int(n_waypoints)
        self.clearance = float(clearance)
        self.rescue_backend = None

    def plan(
        self,
        start: Sequence[float] | np.ndarray,
        subgoal: Sequence[float] | np.ndarray,
        obstacles: Sequence[Sequence[float]] | np.ndarray | None = None,
        warm_start: bool = True,
    ) -> PlanResult:
        """The segment start -> subgoal; ``warm_start`` is accepted and ignored.

        ``velocities`` are zero (the straight line has no timing); ``objective`` is
        ``||x_N - subgoal||^2`` (0 up to rounding) and ``n_considered`` is 0 (no obstacle is
        avoided).
        """
        tic = time.perf_counter()
        start = np.asarray(start, dtype=np.float64).reshape(2)
        subgoal = np.asarray(subgoal, dtype=np.float64).reshape(2)
        t = np.linspace(0.0, 1.0, self.n_waypoints)[:, None]
        waypoints = start + t * (subgoal - start)
        clearance = continuous = np.inf
        obstacles = np.zeros((0, 3)) if obstacles is None else np.asarray(obstacles, float)
        if len(obstacles):
            obstacles = obstacles.reshape(len(obstacles), -1)
            radii = obstacles[:, 2] if obstacles.shape[1] > 2 else np.zeros(len(obstacles))
            gaps = point_distances(waypoints, obstacles[:, :2]) - radii
            clearance = float(gaps.min())
            continuous = float((segment_distances(waypoints, obstacles[:, :2]) - radii).min())
        gap = waypoints[-1] - subgoal
        objective = float(gap @ gap)
        return PlanResult(
            waypoints=waypoints,
            velocities=np.zeros_like(waypoints),
            feasible=bool(clearance >= self.clearance),
            status=STRAIGHT,
            fallback=False,
            escape_mode=False,
            objective=objective,
            min_clearance=clearance,
            min_clearance_continuous=continuous,
            iterations=0,
            solve_time_s=time.perf_counter() - tic,
            backend=STRAIGHT,
            reached_subgoal=True,
        )
