"""What every backend shares: the problem's settings and what follows from them (§3.5.2).

The GP prior of Eq. 3.6 and its reach radii, the certificate, and the problem-level rules every
backend applies the same way: the validated, start-relative problem
(:meth:`ProblemContext.prepare`), the point it aims at (:meth:`~ProblemContext.target`), the
distance a hard-constraint backend is asked to keep (:meth:`~ProblemContext.solver_need`) and
the detour guess (:meth:`~ProblemContext.guess`).
"""

from __future__ import annotations

import numpy as np

from solvers.planner.problem.certificate import Certificate, escape_target
from solvers.planner.problem.gp_prior import GPPrior, build_gp_prior
from solvers.planner.problem.initial_guess import detour_guess
from solvers.planner.problem.preparation import ESCAPE_TOLERANCE, PreparedProblem, prepare
from solvers.planner.problem.settings import ProblemSettings


class ProblemContext:
    """The settings, the GP prior, the reach and the certificate of one planning problem.

    Attributes:
        settings: The validated problem settings.
        prior: GP prior for ``n_waypoints`` and ``dt``.
        reach_radii: Per-waypoint reach under the smoothness budget (N,).
        reach: Farthest any waypoint of an admissible plan can get from the start (m).
        certificate: The check every plan goes through.
    """

    def __init__(self, settings: ProblemSettings, prior: GPPrior | None = None) -> None:
        """``prior``: an already built prior for these settings (e.g. one read from a pickle)."""
        self.settings = settings
        self.prior: GPPrior = (prior if prior is not None
                                else build_gp_prior(settings.n_waypoints, settings.dt))
        self.reach_radii: np.ndarray = self.prior.reach_radii(settings.sigma_smooth)
        self.reach = float(self.reach_radii[-1])
        self.certificate = Certificate(
            n_waypoints=settings.n_waypoints,
            clearance=settings.clearance,
            continuous=settings.continuous,
            goal_tolerance=settings.goal_tolerance,
        )

    def prepare(
        self, start: object, subgoal: object, obstacles: object, *, reach: float
    ) -> PreparedProblem:
        """Validate the inputs (ValueError on bad input) and select the obstacles whose
        clearance disc lies within ``reach`` of the start (the backend's selection radius,
        :attr:`solvers.planner.backends.base.Backend.selection_reach`)."""
        s = self.settings
        return prepare(start, subgoal, obstacles, clearance=s.clearance, reach=reach,
                       max_obstacles=s.max_obstacles)

    def target(self, prep: PreparedProblem) -> np.ndarray:
        """The start-relative point the plan aims at: the subgoal, or the escape target."""
        return escape_target(prep) if prep.escape_mode else prep.goal

    def solver_need(self, prep: PreparedProblem) -> np.ndarray:
        """Distances asked of IPOPT / SCP for the selected obstacles: the clearance plus the
        feasibility margin, or in escape mode the start's distance less a tenth of the escape
        tolerance (the certificate allows the full tolerance)."""
        sel = prep.selected
        return np.where(
            prep.escape[sel],
            prep.start_distances[sel] - 0.1 * ESCAPE_TOLERANCE,
            prep.required[sel] + self.settings.feasibility_margin,
        )

    def guess(self, prep: PreparedProblem) -> np.ndarray:
        """The detour guess towards :meth:`target` around the selected obstacles."""
        sel = prep.selected
        return detour_guess(
            self.prior, self.target(prep), prep.centres[sel], prep.clearances[sel],
            reach=self.reach,
        )
