"""Safe trajectory planner (thesis §3.5.2, Eqs. 3.3-3.8; SPEC §2.2).

Usage::

    from solvers.planner import SafeTrajectoryPlanner
    planner = SafeTrajectoryPlanner(backend="ipopt")
    result = planner.plan(start=[0, 0], subgoal=[2, 1], obstacles=[[1, 0.3], [0.4, -0.8]])
"""

from __future__ import annotations

from solvers.planner.planner import SafeTrajectoryPlanner
from solvers.planner.problem import BACKENDS
from solvers.planner.result import PlanResult
from solvers.planner.suite import PlanningProblem, random_problems

__all__ = ["BACKENDS", "PlanResult", "PlanningProblem", "SafeTrajectoryPlanner", "random_problems"]
