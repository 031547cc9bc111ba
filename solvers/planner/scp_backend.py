"""The SCP backend: convex QPs on OSQP with tangent half-spaces (the program in
:mod:`solvers.planner.scp`).

Every QP solution keeps every waypoint clear when the start iterate does, so the backend starts
from the previous plan or the detour guess (scaled into the smoothness budget) when that is clear
of the selected obstacles, and from the stationary trajectory otherwise.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from solvers.planner.backend import Iterate
from solvers.planner.context import PlanningContext
from solvers.planner.problem import PreparedProblem, bucket_size
from solvers.planner.scp import ScpProgram


class ScpBackend:
    """Solve the prepared problem by sequential convex programming (see the module docstring).

    Attributes:
        context: The planner's settings, prior and certificate.
        programs: OSQP programs by obstacle-slot count; not pickled.
    """

    def __init__(self, context: PlanningContext) -> None:
        self.context = context
        self.programs: dict[int, ScpProgram] = {}

    def program(self, n_slots: int) -> ScpProgram:
        """The OSQP program for ``n_slots`` obstacle slots (set up once)."""
        if n_slots not in self.programs:
            s = self.context.settings
            self.programs[n_slots] = ScpProgram(
                self.context.prior, n_slots, smooth_regulariser=s.smooth_weight,
                continuous=s.continuous,
            )
        return self.programs[n_slots]

    def warmup(self, slot_counts: Iterable[int]) -> None:
        """Set up the programs for these slot counts now."""
        for count in slot_counts:
            self.program(count)

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """SCP from the first clear candidate (previous plan, detour guess) or the stationary
        trajectory."""
        context = self.context
        s = context.settings
        prep = prepared
        sel = prep.selected
        need = context.solver_need(prep)
        exact_need = np.where(
            prep.escape[sel], need, prep.required[sel] + 0.5 * s.feasibility_margin
        )
        z0 = np.zeros(context.prior.n_var)
        guess = context.guess(prep)
        candidates = [c for c in (warm, guess) if c is not None]
        for candidate in candidates:
            h = context.prior.smoothness(candidate)
            if h > s.sigma_smooth:
                candidate = candidate * np.sqrt(s.sigma_smooth / h) * (1.0 - 1e-9)
            if context.certificate.clear_of(prep, candidate, sel, need):
                z0 = candidate
                break
        program = self.program(bucket_size(len(sel), s.max_obstacles))
        outcome = program.solve(
            z0,
            context.target(prep),
            prep.centres[sel],
            need,
            sigma_smooth=s.sigma_smooth,
            trust_region=s.scp_trust_region,
            max_iterations=s.scp_max_iterations,
            exact_need=exact_need,
        )
        return Iterate(outcome.z, outcome.status, outcome.iterations)

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the OSQP programs; they are set up again lazily."""
        return {**self.__dict__, "programs": {}}
