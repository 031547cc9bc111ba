"""The interface between the planner and its backends: a prepared problem in, an iterate out.

Each backend (:mod:`~solvers.planner.backends.ipopt`, :mod:`~solvers.planner.backends.lm`,
:mod:`~solvers.planner.backends.scp`) solves the problem of thesis Eqs. 3.3-3.7 for the
obstacles the preparation selected and returns its raw
:class:`~solvers.planner.problem.certificate.Iterate`; the planner then certifies it whichever
backend produced it. A backend is built from its own frozen settings object
(``settings.build(context)``), which is what ``conf/planner/*.yaml``'s ``backend:`` node
instantiates.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Protocol, runtime_checkable

import numpy as np

from solvers.planner.problem.certificate import Iterate
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.preparation import PreparedProblem

#: Slack (m) added to the reach of a hard-constraint backend (IPOPT, SCP) when obstacles are
#: selected: obstacles whose clearance disc is at most this far beyond every admissible plan are
#: still given to the backend. (The LM backend uses its hinge margin instead; before the backends
#: had their own settings, every backend used that margin, whose default this is.)
SELECTION_SLACK = 0.02


@runtime_checkable
class Backend(Protocol):
    """A solver backend: compiled programs are built lazily, per obstacle-slot count, and are
    not pickled (a copy rebuilds them on first use).

    Attributes:
        selection_reach: Obstacles whose clearance disc lies farther than this from the start
            (m) are not given to the backend (the certificate still checks them).
    """

    selection_reach: float

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """Plan for ``prepared``; ``warm`` is an optional initial guess (receding horizon)."""
        ...

    def warmup(self, slot_counts: Iterable[int]) -> None:
        """Build the compiled programs for these obstacle-slot counts now."""
        ...


class BackendSettings(Protocol):
    """A backend's frozen settings: ``name`` (``"ipopt"``, ``"lm"``, ``"scp"``) and the
    backend they build for a problem."""

    name: str

    def build(self, context: ProblemContext) -> Backend:
        """The backend with these settings for ``context``'s problem."""
        ...


def hard_constraint_reach(context: ProblemContext) -> float:
    """The selection radius of IPOPT and SCP: the exact reach plus the feasibility margin and
    :data:`SELECTION_SLACK`."""
    return context.reach + context.settings.feasibility_margin + SELECTION_SLACK


def bucket_size(count: int, max_obstacles: int) -> int:
    """Compiled obstacle-slot count for ``count`` obstacles: 0 or the next power of two (capped)."""
    if count <= 0:
        return 0
    return min(max_obstacles, 1 << math.ceil(math.log2(count)))
