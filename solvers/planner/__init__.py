"""Safe trajectory planner (thesis §3.5.2, Eqs. 3.3-3.8).

Usage::

    from solvers.planner import SafeTrajectoryPlanner
    planner = SafeTrajectoryPlanner(backend="ipopt")
    result = planner.plan(start=[0, 0], subgoal=[2, 1], obstacles=[[1, 0.3], [0.4, -0.8]])

The layout (one job per module) is described in solvers/README.md, "Code layout".
"""

from __future__ import annotations

from solvers.planner.batching import plan_batch, start_batch_workers
from solvers.planner.compare import Comparison, ComparisonRow, compare, compare_backends
from solvers.planner.planner import SafeTrajectoryPlanner
from solvers.planner.protocol import Planner
from solvers.planner.result import PlanResult
from solvers.planner.settings import BACKENDS, PlannerSettings
from solvers.planner.suite import PlanningProblem, random_problems

__all__ = [
    "BACKENDS",
    "Comparison",
    "ComparisonRow",
    "PlanResult",
    "Planner",
    "PlannerSettings",
    "PlanningProblem",
    "SafeTrajectoryPlanner",
    "compare",
    "compare_backends",
    "plan_batch",
    "random_problems",
    "start_batch_workers",
]
