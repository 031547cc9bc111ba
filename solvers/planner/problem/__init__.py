"""The planning problem of thesis §3.5.2 (Eqs. 3.3-3.7), apart from the solvers of
:mod:`solvers.planner.backends`.

* :mod:`.settings` -- :class:`ProblemSettings`, the problem's keys;
* :mod:`.gp_prior` -- the trajectory variables and h_smooth (Eqs. 3.5, 3.6);
* :mod:`.preparation` -- inputs validated, start-relative, obstacles selected (Eq. 3.7's
  clearances, escape mode);
* :mod:`.initial_guess` -- the detour guess;
* :mod:`.certificate` -- the exact clearance check, the fallback and the result (Eq. 3.7);
* :mod:`.context` -- :class:`ProblemContext`: the above for one set of settings.

The NLP itself (Eq. 3.3) is written by each backend in its own form: hard constraints
(:mod:`solvers.planner.backends.ipopt`, :mod:`solvers.planner.backends.scp`) or the penalty of
Eq. 3.8 (:mod:`solvers.planner.backends.lm`).
"""

from __future__ import annotations

from solvers.planner.problem.certificate import Certificate, Iterate, escape_target
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior, build_gp_prior, join, split
from solvers.planner.problem.initial_guess import detour_guess
from solvers.planner.problem.preparation import (
    ESCAPE_TOLERANCE,
    PreparedProblem,
    prepare,
    validate_obstacles,
    validate_point,
)
from solvers.planner.problem.settings import ProblemSettings, problem_keys

__all__ = [
    "ESCAPE_TOLERANCE",
    "Certificate",
    "GPPrior",
    "Iterate",
    "PreparedProblem",
    "ProblemContext",
    "ProblemSettings",
    "build_gp_prior",
    "detour_guess",
    "escape_target",
    "join",
    "prepare",
    "problem_keys",
    "split",
    "validate_obstacles",
    "validate_point",
]
