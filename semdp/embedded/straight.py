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
        problem: the planning problem (:class:`~solvers.planner.ProblemSettings`, its defaults
            if None), as the optimising planners take it; of it the line uses ``n_waypoints``
            (points on the segment, the start included) and ``clearance`` (only to fill
            ``feasible``: every waypoint >= clearance + r away).
        backend, rescue_backend: must be None; accepted so that every ``conf/planner`` entry
            shares the keys (the optimising planners name their backend and ``"ipopt"``).

    Raises:
        ValueError: a ``backend`` or a ``rescue_backend``.
    """

    def __init__(self, problem: ProblemSettings | None = None, backend: None = None,
                 rescue_backend: str | None = None) -> None:
        for name, value in (("backend", backend), ("rescue_backend", rescue_backend)):
            if value is not None:
                raise ValueError(f"the straight-line ablation planner has no solver: {name} "
                                 f"must be None, got {value!r}")
        self.problem = ProblemSettings() if problem is None else problem
        if not isinstance(self.problem, ProblemSettings):
            raise ValueError(f"problem must be a ProblemSettings, got {self.problem!r}")
        self.rescue_backend = None

    @property
    def n_waypoints(self) -> int:
        """Points on the segment, the start included."""
        return self.problem.n_waypoints

    @property
    def clearance(self) -> float:
        """eps' (m): the clearance ``feasible`` reports against."""
        return self.problem.clearance

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
