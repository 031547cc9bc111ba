"""The Levenberg-Marquardt backend: the thesis' penalty form (Eq. 3.8, App. B.2.3; the kernel in
:mod:`solvers.planner.lm`).

Fixed lambda (training) or lambda doubled until the plan passes the certificate, up to
``lm_lambda_max`` (evaluation); escape mode uses ``lm_lambda_max`` at once. A penalty plan that
still fails the certificate is shrunk towards the start before the planner falls back.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from solvers.planner.backend import Iterate
from solvers.planner.context import PlanningContext
from solvers.planner.lm import LMKernel, LMWeights, build_lm_functions, levenberg_marquardt
from solvers.planner.problem import ESCAPE_TOLERANCE, PreparedProblem, bucket_size

#: Budget weight (relative to lambda) used only to rank LM's initial guesses.
CANDIDATE_BUDGET_FACTOR = 0.01


class LMBackend:
    """Solve the prepared problem with Levenberg-Marquardt (see the module docstring).

    Attributes:
        context: The planner's settings, prior and certificate.
        weights: The penalty weights of Eq. 3.8.
        kernels: Compiled kernels by obstacle-slot count; not pickled.
    """

    def __init__(self, context: PlanningContext) -> None:
        s = context.settings
        self.context = context
        self.weights = LMWeights(
            smooth_regulariser=s.smooth_weight,
            smooth_budget=s.lm_budget_weight,
            obstacle=s.lm_obstacle_weight,
            sigma_smooth=s.sigma_smooth,
        )
        self.kernels: dict[int, LMKernel] = {}

    def kernel(self, n_slots: int) -> LMKernel:
        """The compiled kernel for ``n_slots`` obstacle slots (built once)."""
        if n_slots not in self.kernels:
            step, cost = build_lm_functions(
                self.context.prior, self.weights, n_slots,
                continuous=self.context.settings.continuous,
            )
            self.kernels[n_slots] = LMKernel(step, cost, self.context.settings.n_waypoints)
        return self.kernels[n_slots]

    def warmup(self, slot_counts: Iterable[int]) -> None:
        """Build the kernels for these slot counts now."""
        for count in slot_counts:
            self.kernel(count)

    def params(
        self, prep: PreparedProblem, n_slots: int, lam: float, budget_factor: float = 1.0
    ) -> np.ndarray:
        """The kernel's parameter vector: target, obstacle slots, radii, weights."""
        sel = prep.selected
        m = len(sel)
        centres = np.zeros((n_slots, 2))
        centres[:m] = prep.centres[sel]
        radii = np.zeros(n_slots)
        # escape obstacles: "no closer than the start", without margin (the first waypoints
        # cannot get farther than the start at once; the target pulls away from them anyway)
        radii[:m] = np.where(
            prep.escape[sel],
            prep.start_distances[sel] - 0.1 * ESCAPE_TOLERANCE,
            prep.required[sel] + self.context.settings.lm_margin,
        )
        # escape mode: the target is outside the violated clearances and weighs as much as the
        # constraints (lambda_max), so the plan actually leaves
        goal_scale = np.sqrt(lam) if prep.escape_mode else 1.0
        return np.concatenate(
            [self.context.target(prep), centres.ravel(), radii,
             [lam, lam * budget_factor, goal_scale]]
        )

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """LM from the best initial guess, lambda rounds, then :meth:`repair`."""
        s = self.context.settings
        passes = self.context.certificate.passes
        prep = prepared
        n_slots = bucket_size(len(prep.selected), s.max_obstacles)
        kernel = self.kernel(n_slots)
        lam = s.lm_lambda_max if prep.escape_mode else s.lm_lambda
        # rank the initial guesses by goal distance and clearance, barely by the budget: LM
        # repairs a budget overrun quickly, while a stationary start cannot pick a side around
        # an obstacle that sits exactly on the straight line
        kernel.p[:] = self.params(prep, n_slots, lam, CANDIDATE_BUDGET_FACTOR)
        z = min(self.candidates(prep, warm), key=kernel.cost_at)
        total = 0
        while True:
            kernel.p[:] = self.params(prep, n_slots, lam)
            z, _, done = levenberg_marquardt(
                kernel, z, iterations=s.lm_iterations, damping=s.lm_damping
            )
            total += done
            if not s.lm_adaptive or lam >= s.lm_lambda_max or passes(prep, z):
                break
            lam = min(2.0 * lam, s.lm_lambda_max)
        return self.repair(prep, Iterate(z, "solved", total, lam))

    def repair(self, prep: PreparedProblem, plan: Iterate) -> Iterate:
        """Shrink a penalty plan that fails the certificate towards the start.

        ``theta z`` (every waypoint moved towards the start by the factor theta, velocities
        likewise) is exactly as smooth up to ``theta^2``; the largest theta in 0.9, 0.8, ... 0.1
        that passes the certificate is kept (status ``solved_shortened``) before falling back to
        the stationary trajectory.
        """
        passes = self.context.certificate.passes
        if passes(prep, plan.z):
            return plan
        for theta in np.arange(0.9, 0.05, -0.1):
            if passes(prep, theta * plan.z):
                return Iterate(theta * plan.z, f"solved_shortened(theta={theta:.1f})",
                               plan.iterations, plan.multiplier)
        return plan

    def candidates(self, prep: PreparedProblem, warm: np.ndarray | None) -> list[np.ndarray]:
        """Initial guesses for LM; the one with the lowest penalty cost is used.

        The detour guess, the straight smoothest path to the (reach-clipped) goal, each scaled
        towards the start to fit the smoothness budget, and the stationary trajectory (the
        thesis' initialisation, hinge-free whenever the start is clear).
        """
        context = self.context
        sigma = context.settings.sigma_smooth
        goal = context.target(prep)
        distance = float(np.hypot(*goal))
        target = goal if distance <= context.reach else goal * (context.reach / distance)
        candidates = [np.zeros(context.prior.n_var), context.prior.goal_map @ target]
        if len(prep.selected):
            detour = context.guess(prep)
            candidates.append(detour)
            h = context.prior.smoothness(detour)
            if h > sigma:
                candidates.append(detour * np.sqrt(sigma / h))
        if warm is not None:
            candidates.append(warm)
        return candidates

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the compiled kernels (CasADi objects); they are rebuilt lazily."""
        return {**self.__dict__, "kernels": {}}
