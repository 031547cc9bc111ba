"""The interface between the planner and its backends: a prepared problem in, an iterate out.

Each backend (:mod:`~solvers.planner.ipopt_backend`, :mod:`~solvers.planner.lm_backend`,
:mod:`~solvers.planner.scp_backend`) solves the problem of thesis Eqs. 3.3-3.7 for the obstacles
the preparation selected and returns its raw :class:`Iterate`; the planner then certifies it
(:mod:`~solvers.planner.certificate`) whichever backend produced it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from solvers.planner.problem import PreparedProblem


@dataclass
class Iterate:
    """A backend's plan before the certificate.

    Attributes:
        z: Trajectory variables in the start-relative frame (layout in
            :mod:`solvers.planner.problem`).
        status: Short text: ``solved``, ``max_iter``, ``solved_shortened(theta=0.8)`` ...
        iterations: Solver iterations (IPOPT iterations, LM iterations over every lambda round,
            or QP solves).
        multiplier: LM's penalty multiplier lambda (``nan`` for the other backends).
        failed: The backend raised; ``z`` is meaningless and the planner falls back.
        rescued: ``z`` is the rescue backend's plan, which passed the certificate.
    """

    z: np.ndarray
    status: str
    iterations: int
    multiplier: float = float("nan")
    failed: bool = False
    rescued: bool = False


@runtime_checkable
class Backend(Protocol):
    """A solver backend: compiled programs are built lazily, per obstacle-slot count, and are
    not pickled (a copy rebuilds them on first use)."""

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """Plan for ``prepared``; ``warm`` is an optional initial guess (receding horizon)."""
        ...

    def warmup(self, slot_counts: Iterable[int]) -> None:
        """Build the compiled programs for these obstacle-slot counts now."""
        ...
