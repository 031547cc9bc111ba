"""The ``Planner`` protocol: what the Safety-Embedded MDP needs of a planner (thesis Alg. 2).

The SEMDP wrapper (``semdp/embedded/wrapper.py``) calls ``plan(start, subgoal, obstacles,
warm_start=...)`` once per high-level step and reads the result's ``waypoints`` and certificate
fields (``feasible``, ``fallback``, ``escape_mode``, ``rescued``, ``min_clearance``); the safety
evaluation reads the planner's ``clearance`` (eps'). Every planner satisfies it: the three
backends through :class:`~solvers.planner.SafeTrajectoryPlanner` and the obstacle-blind
straight-line ablation planner (``semdp/embedded/straight.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from solvers.planner.result import PlanResult


@runtime_checkable
class Planner(Protocol):
    """A planner: N waypoints from a start towards a subgoal, with their certificate.

    ``isinstance(obj, Planner)`` checks that the members exist (not their signatures).
    """

    @property
    def n_waypoints(self) -> int:
        """N, waypoints of every plan, the start included."""
        ...

    @property
    def clearance(self) -> float:
        """eps' (m): the clearance the certificate fields are measured against."""
        ...

    def plan(
        self,
        start: Sequence[float] | np.ndarray,
        subgoal: Sequence[float] | np.ndarray,
        obstacles: Sequence[Sequence[float]] | np.ndarray | None = None,
        warm_start: bool = True,
    ) -> PlanResult:
        """Plan from ``start`` towards ``subgoal`` around ``obstacles`` ((m, 2) or (m, 3))."""
        ...
