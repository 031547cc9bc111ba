"""What the planner and its backends share: the settings and what follows from them.

The GP prior of Eq. 3.6 and its reach radii, the certificate, and the problem-level rules every
backend applies the same way: which obstacles a backend sees (:meth:`PlanningContext.prepare`),
the point it aims at (:meth:`~PlanningContext.target`), the distance a hard-constraint backend is
asked to keep (:meth:`~PlanningContext.solver_need`) and the detour guess
(:meth:`~PlanningContext.guess`).
"""

from __future__ import annotations

import numpy as np

from solvers.planner.certificate import Certificate, escape_target
from solvers.planner.problem import (
    ESCAPE_TOLERANCE,
    GPPrior,
    PreparedProblem,
    build_gp_prior,
    detour_guess,
    prepare,
)
from solvers.planner.settings import PlannerSettings


class PlanningContext:
    """The settings, the GP prior, the reach and the certificate of one planner.

    Attributes:
        settings: The validated settings.
        prior: GP prior for ``n_waypoints`` and ``dt``.
        reach_radii: Per-waypoint reach under the smoothness budget (N,).
        reach: Farthest any waypoint of an admissible plan can get from the start (m).
        certificate: The check every plan goes through.
    """

    def __init__(self, settings: PlannerSettings) -> None:
        self.settings = settings
        self.prior: GPPrior = build_gp_prior(settings.n_waypoints, settings.dt)
        self.reach_radii: np.ndarray = self.prior.reach_radii(settings.sigma_smooth)
        self.reach = float(self.reach_radii[-1])
        self.certificate = Certificate(
            n_waypoints=settings.n_waypoints,
            clearance=settings.clearance,
            continuous=settings.continuous,
            goal_tolerance=settings.goal_tolerance,
        )

    def prepare(self, start: object, subgoal: object, obstacles: object) -> PreparedProblem:
        """Validate the inputs and select the obstacles the backend is given (ValueError on
        bad input); obstacles beyond the reach plus margins are dropped."""
        s = self.settings
        reach = self.reach
        if s.backend == "lm":
            # The penalty budget is soft: allow the plan to overrun it (the bound is used only
            # to drop far obstacles; the certificate still checks all of them).
            reach = float(np.sqrt(4.0 * s.sigma_smooth / self.prior.reach_coef[-1]))
        return prepare(
            start,
            subgoal,
            obstacles,
            clearance=s.clearance,
            reach=reach + s.feasibility_margin + s.lm_margin,
            max_obstacles=s.max_obstacles,
        )

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
