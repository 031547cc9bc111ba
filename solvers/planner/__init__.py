"""Safe trajectory planner (thesis §3.5.2, Eqs. 3.3-3.8).

Usage::

    from solvers.planner import LMSettings, ProblemSettings, SafeTrajectoryPlanner
    planner = SafeTrajectoryPlanner(backend="ipopt")            # a backend's defaults
    planner = SafeTrajectoryPlanner(backend=LMSettings(adaptive=True),
                                    problem=ProblemSettings(clearance=0.6))
    result = planner.plan(start=[0, 0], subgoal=[2, 1], obstacles=[[1, 0.3], [0.4, -0.8]])

The problem (:mod:`.problem`) is apart from its solvers (:mod:`.backends`, one module and one
settings class each); the layout is described in docs/planner.md, "Code layout". Files of
earlier versions (flat config nodes, old pickles) are read by :mod:`.legacy` only.
"""

from __future__ import annotations

from solvers.planner.backends import BACKENDS, IpoptSettings, LMSettings, SCPSettings
from solvers.planner.batch import plan_batch, start_batch_workers
from solvers.planner.compare import Comparison, ComparisonRow, compare, compare_backends
from solvers.planner.planner import SafeTrajectoryPlanner
from solvers.planner.problem import ProblemSettings
from solvers.planner.protocol import Planner
from solvers.planner.result import PlanResult
from solvers.planner.settings import PlannerSettings
from solvers.planner.suite import PlanningProblem, random_problems

__all__ = [
    "BACKENDS",
    "Comparison",
    "ComparisonRow",
    "IpoptSettings",
    "LMSettings",
    "PlanResult",
    "Planner",
    "PlannerSettings",
    "PlanningProblem",
    "ProblemSettings",
    "SCPSettings",
    "SafeTrajectoryPlanner",
    "compare",
    "compare_backends",
    "plan_batch",
    "random_problems",
    "start_batch_workers",
]
