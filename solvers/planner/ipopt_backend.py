"""The IPOPT backend: hard pairwise clearance constraints (Eq. 3.3; the NLP in
:mod:`solvers.planner.ipopt`).

Two attempts: a short one from the detour guess (or the previous plan), kept when it passes the
certificate, then a cold one from the stationary trajectory, which is feasible whenever the start
is (thesis §3.5.2). A guess-only start was faster in the median but failed on 2-3 % of the tuning
problems (solvers/README.md, "Calibration"). Escape mode skips the first attempt.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from solvers.planner.backend import Iterate
from solvers.planner.context import PlanningContext
from solvers.planner.ipopt import IPOPT_OPTIONS, IpoptProgram, build_ipopt, solve_ipopt
from solvers.planner.problem import PreparedProblem, bucket_size

#: The two attempts and their compiled programs (they differ in the iteration cap).
ATTEMPTS: tuple[str, ...] = ("first", "cold")

_STATUS = {
    "Solve_Succeeded": "solved",
    "Solved_To_Acceptable_Level": "solved_acceptable",
    "Maximum_Iterations_Exceeded": "max_iter",
    "Maximum_WallTime_Exceeded": "max_wall_time",
}


def ipopt_status(status: str) -> str:
    """IPOPT's return status as the planner reports it (``solved``, ``max_iter`` ...)."""
    return _STATUS.get(status, status)


class IpoptBackend:
    """Solve the prepared problem with IPOPT (see the module docstring).

    Attributes:
        context: The planner's settings, prior and certificate.
        options: IPOPT options: :data:`IPOPT_OPTIONS` with the settings' ``ipopt_options`` over.
        programs: Compiled programs by (obstacle-slot count, attempt); not pickled.
    """

    def __init__(self, context: PlanningContext) -> None:
        self.context = context
        self.options: dict[str, object] = dict(IPOPT_OPTIONS, **context.settings.ipopt_options)
        self.programs: dict[tuple[int, str], IpoptProgram] = {}

    def program(self, n_slots: int, attempt: str) -> IpoptProgram:
        """The compiled program for ``n_slots`` obstacle slots and ``attempt`` (built once)."""
        key = (n_slots, attempt)
        if key not in self.programs:
            s = self.context.settings
            options = dict(self.options)
            options["max_iter"] = s.ipopt_first_max_iter if attempt == "first" else s.ipopt_max_iter
            self.programs[key] = build_ipopt(
                self.context.prior,
                n_slots,
                smooth_regulariser=s.smooth_weight,
                continuous=s.continuous,
                ipopt_options=options,
            )
        return self.programs[key]

    def warmup(self, slot_counts: Iterable[int], attempts: Iterable[str] = ATTEMPTS) -> None:
        """Build the programs of ``attempts`` for these slot counts now."""
        kinds = tuple(attempts)
        for count in slot_counts:
            for attempt in kinds:
                self.program(count, attempt)

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """Plan with IPOPT: the first attempt if it passes the certificate, else the cold one."""
        context = self.context
        s = context.settings
        prep = prepared
        sel = prep.selected
        n_slots = bucket_size(len(sel), s.max_obstacles)
        args = (context.target(prep), prep.centres[sel], context.solver_need(prep),
                context.reach_radii)
        kwargs = {"sigma_smooth": s.sigma_smooth}
        iterations = 0
        if s.ipopt_first_max_iter > 0 and not prep.escape_mode:
            z0 = warm if warm is not None else context.guess(prep)
            first = solve_ipopt(self.program(n_slots, "first"), context.prior, z0, *args,
                                **kwargs)
            iterations += max(first.iterations, 0)
            if first.success and context.certificate.passes(prep, first.z):
                return Iterate(first.z, ipopt_status(first.status), iterations)
        # cold attempt from the stationary trajectory, which is feasible
        second = solve_ipopt(self.program(n_slots, "cold"), context.prior,
                             np.zeros(context.prior.n_var), *args, **kwargs)
        iterations += max(second.iterations, 0)
        return Iterate(second.z, ipopt_status(second.status), iterations)

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the compiled programs (CasADi objects); they are rebuilt lazily."""
        return {**self.__dict__, "programs": {}}
