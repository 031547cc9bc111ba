"""The Levenberg-Marquardt backend: the thesis' penalty/dual form (Eq. 3.8, App. B.2.3).

For a multiplier ``lambda`` (one value for all constraints, App. B.2.3) the inner problem is the
nonlinear least-squares problem with residuals

* ``x_N - g`` (the objective f_goal, Eq. 3.4),
* ``sqrt(rho) W z`` (a small smoothness regulariser, also in the other backends' objective),
* ``sqrt(lambda w_smooth) (sqrt(h_smooth / sigma_smooth) - 1)_+`` (the smoothness budget,
  Eq. 3.6; the square root makes the residual a norm, which Gauss-Newton linearises well),
* ``sqrt(lambda w_obstacle) (c_j - d_ij)_+`` (the hinge of Eq. 3.7; with the continuous option
  ``d_ij`` is the distance of segment ``[x_i, x_{i+1}]`` to obstacle j).

The start constraint (Eq. 3.5) is exact: ``x_1`` and ``v_1`` are not variables. Fixed lambda
(training) or lambda doubled until the plan passes the certificate, up to ``lambda_max``
(evaluation); escape mode uses ``lambda_max`` at once. A penalty plan that still fails the
certificate is shrunk towards the start before the planner falls back. The knobs are those of
:class:`LMSettings` (``conf/planner/lm.yaml``).

Structure: with the variables ordered waypoint by waypoint (``[x_i, v_i]``, the "w" order), every
residual except the budget touches two consecutive waypoints, so ``J^T J`` is a band matrix
(bandwidth 7) plus the rank-one budget term ``a a^T``. One CasADi SX function per compiled
obstacle-slot count returns the cost, ``J^T r``, the band and ``a``; the damped steps are taken
by :mod:`solvers.planner.backends.banded_least_squares` (one banded Cholesky solve each).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from solvers.native import cache_dir, compiler, native_function
from solvers.planner.backends.banded_least_squares import BandedKernel
from solvers.planner.backends.base import bucket_size
from solvers.planner.backends.native_lm import native_banded_kernel
from solvers.planner.geometry import symbolic_distance
from solvers.planner.problem.certificate import Iterate
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.preparation import ESCAPE_TOLERANCE, PreparedProblem
from solvers.planner.problem.settings import ProblemSettings
from solvers.planner.validation import count, flag, non_negative, positive, set_field

_DISTANCE_EPS = 1e-12
#: Lower bandwidth of ``J^T J`` without the budget row in the w order (two waypoints x 4 - 1).
BANDWIDTH = 7


@dataclass(frozen=True)
class LMSettings:
    """The LM backend's knobs, validated (``ValueError`` names the key and the value).

    Attributes:
        iterations: LM iterations per lambda (thesis: 10 in training).
        lambda_: The multiplier lambda of Eq. 3.8 (fixed mode; the start of adaptive mode).
        adaptive: Double lambda until the plan passes the certificate, up to ``lambda_max``
            (App. B.2.3; the evaluation setting).
        lambda_max: Largest lambda, also used in escape mode (thesis: 1024).
        obstacle_weight: Base weight of the obstacle hinge (times lambda).
        budget_weight: Base weight of the smoothness-budget hinge (times lambda).
        margin: Extra clearance (m) in the hinge, so penalty solutions usually pass the exact
            certificate (the public code adds 0.01 m).
        damping: Initial Marquardt damping.
        native: Run the kernels and the LM iteration as native code (the default: C compiled
            once per machine and cached: :mod:`solvers.native`,
            :mod:`solvers.planner.backends.native_lm`); the same floats as CasADi's virtual
            machine and the Python iteration (``False``), about 2x faster plans; the virtual
            machine where no C compiler is found.
    """

    name: ClassVar[str] = "lm"

    iterations: int = 10
    lambda_: float = 1.0
    adaptive: bool = False
    lambda_max: float = 1024.0
    obstacle_weight: float = 1000.0
    budget_weight: float = 100.0
    margin: float = 0.02
    damping: float = 1e-4
    native: bool = field(default=True, compare=False)  # how, not what: same floats

    def __post_init__(self) -> None:
        for name in ("lambda_", "lambda_max", "obstacle_weight", "budget_weight", "damping"):
            set_field(self, name, positive(name, getattr(self, name)))
        set_field(self, "margin", non_negative("margin", self.margin))
        set_field(self, "iterations", count("iterations", self.iterations, 1))
        set_field(self, "adaptive", flag("adaptive", self.adaptive))
        set_field(self, "native", flag("native", self.native))
        if self.lambda_ > self.lambda_max:
            raise ValueError(f"lambda_ ({self.lambda_}) must be <= lambda_max ({self.lambda_max})")

    def build(self, context: ProblemContext) -> LMBackend:
        """The LM backend for ``context``'s problem."""
        return LMBackend(context, self)


def w_order(n_waypoints: int) -> np.ndarray:
    """Permutation ``perm`` with ``w = z[perm]`` (z: positions then velocities; w: per waypoint)."""
    n = n_waypoints - 1
    perm = np.empty(4 * n, dtype=int)
    for i in range(n):
        perm[4 * i : 4 * i + 2] = [2 * i, 2 * i + 1]
        perm[4 * i + 2 : 4 * i + 4] = [2 * n + 2 * i, 2 * n + 2 * i + 1]
    return perm


def build_lm_functions(
    prior: GPPrior, problem: ProblemSettings, settings: LMSettings, n_slots: int
) -> tuple[ca.Function, ca.Function]:
    """CasADi functions ``step(w, p) -> (F, J^T r, band, a)`` and ``cost(w, p) -> F``.

    ``w`` is the trajectory in the w order (:func:`w_order`); the weights are ``problem``'s rho
    and ``sigma_smooth`` and ``settings``' base weights. ``band`` is ``(n, 8)`` with
    ``band[i, d] = (J_s^T J_s)[i + d, i]`` (``J_s``: all rows but the budget row, whose gradient is
    ``a``), so ``J^T J = band matrix + a a^T``.

    ``p = [g (2), centres (2 n_slots, row-major), clearances (n_slots), lambda, lambda_budget,
    goal_scale]``;
    a clearance of 0 disables its slot (the hinge is then identically zero). The solve uses
    ``lambda_budget = lambda`` (one multiplier, App. B.2.3); a smaller value only serves to rank
    initial guesses.
    """
    n = prior.n_waypoints - 1
    n_var = prior.n_var
    continuous = problem.continuous
    w = ca.SX.sym("w", n_var)
    perm = w_order(prior.n_waypoints)
    inverse = np.argsort(perm)
    z = ca.vertcat(*[w[int(k)] for k in inverse])  # z[k] = w[inverse[k]]
    p = ca.SX.sym("p", 5 + 3 * n_slots)
    goal = p[0:2]
    lam = p[2 + 3 * n_slots]
    lam_budget = p[3 + 3 * n_slots]
    goal_scale = p[4 + 3 * n_slots]
    positions = [ca.vertcat(0.0, 0.0)] + [z[2 * i : 2 * i + 2] for i in range(n)]
    smooth_res = ca.mtimes(ca.DM(prior.W), z)
    h = ca.sumsqr(smooth_res)
    residuals = [
        goal_scale * (positions[-1] - goal),
        np.sqrt(problem.smooth_weight) * smooth_res,
    ]
    obstacle_scale = ca.sqrt(lam * settings.obstacle_weight)
    for j in range(n_slots):
        centre = p[2 + 2 * j : 4 + 2 * j]
        radius = p[2 + 2 * n_slots + j]
        for i in range(1, n + 1):
            ends = (positions[i - 1], positions[i]) if continuous else (positions[i], None)
            distance = symbolic_distance(*ends, centre, eps=_DISTANCE_EPS)
            residuals.append(obstacle_scale * ca.fmax(0.0, radius - distance))
    r_band = ca.vertcat(*residuals)
    r_budget = ca.sqrt(lam_budget * settings.budget_weight) * ca.fmax(
        0.0, ca.sqrt(h + _DISTANCE_EPS) / np.sqrt(problem.sigma_smooth) - 1.0
    )
    jac = ca.jacobian(r_band, w)
    grad_budget = ca.jacobian(r_budget, w).T
    gram = ca.mtimes(jac.T, jac)
    band = ca.SX.zeros(n_var, BANDWIDTH + 1)
    for d in range(BANDWIDTH + 1):
        for i in range(n_var - d):
            band[i, d] = gram[i + d, i]
    cost = ca.sumsqr(r_band) + r_budget**2
    gradient = ca.mtimes(jac.T, r_band) + grad_budget * r_budget
    step = ca.Function(
        f"lm_step_{n_slots}", [w, p], [cost, gradient, ca.densify(band), ca.densify(grad_budget)]
    )
    cost_fn = ca.Function(f"lm_cost_{n_slots}", [w, p], [cost])
    return step, cost_fn


#: Budget weight (relative to lambda) used only to rank LM's initial guesses.
CANDIDATE_BUDGET_FACTOR = 0.01


#: Kernels built in this process, by problem, settings, slot count and prior: the LM backends of
#: equal problems (the planners of lockstep envs) share them instead of building each (0.05-0.1 s
#: apiece). A kernel keeps nothing between calls: its parameters are set before every use.
_KERNELS: dict[tuple[object, ...], BandedKernel] = {}


class LMBackend:
    """Solve the prepared problem with Levenberg-Marquardt (see the module docstring).

    Attributes:
        context: The problem's settings, prior and certificate.
        settings: The LM knobs (penalty weights of Eq. 3.8, lambda schedule, margin).
        selection_reach: Obstacles beyond this (m) are not given to LM: the budget is a penalty,
            so the plan may overrun it (twice the exact reach), plus the margins.
        kernels: Compiled kernels by obstacle-slot count; not pickled.
    """

    def __init__(self, context: ProblemContext, settings: LMSettings) -> None:
        s = context.settings
        self.context = context
        self.settings = settings
        soft_reach = float(np.sqrt(4.0 * s.sigma_smooth / context.prior.reach_coef[-1]))
        self.selection_reach = soft_reach + s.feasibility_margin + settings.margin
        self.kernels: dict[int, BandedKernel] = {}

    def kernel(self, n_slots: int) -> BandedKernel:
        """The compiled kernel for ``n_slots`` obstacle slots (built once per process for equal
        problems and settings, see :data:`_KERNELS`)."""
        if n_slots not in self.kernels:
            prior = self.context.prior
            key = (self.context.settings, self.settings, self.settings.native, n_slots,
                   hashlib.sha256(prior.W.tobytes() + prior.goal_map.tobytes()).hexdigest(),
                   (compiler(), str(cache_dir())) if self.settings.native else None)
            if key not in _KERNELS:
                _KERNELS[key] = self._build_kernel(n_slots)
            self.kernels[n_slots] = _KERNELS[key]
        return self.kernels[n_slots]

    def _build_kernel(self, n_slots: int) -> BandedKernel:
        """The iteration in C where possible, else the kernels in C, else CasADi's VM."""
        problem = self.context.settings
        step, cost = build_lm_functions(self.context.prior, problem, self.settings, n_slots)
        perm = w_order(problem.n_waypoints)
        if not self.settings.native:
            return BandedKernel(step, cost, perm)
        return native_banded_kernel(step, cost, perm) or BandedKernel(
            native_function(step) or step, native_function(cost) or cost, perm)

    def warmup(self, slot_counts: Iterable[int]) -> None:
        """Build the kernels for these slot counts now."""
        for slots in slot_counts:
            self.kernel(slots)

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
            prep.required[sel] + self.settings.margin,
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
        s = self.settings
        passes = self.context.certificate.passes
        prep = prepared
        n_slots = bucket_size(len(prep.selected), self.context.settings.max_obstacles)
        kernel = self.kernel(n_slots)
        lam = s.lambda_max if prep.escape_mode else s.lambda_
        # rank the initial guesses by goal distance and clearance, barely by the budget: LM
        # repairs a budget overrun quickly, while a stationary start cannot pick a side around
        # an obstacle that sits exactly on the straight line
        kernel.p[:] = self.params(prep, n_slots, lam, CANDIDATE_BUDGET_FACTOR)
        z = min(self.candidates(prep, warm), key=kernel.cost_at)
        kernel.p[-2] = lam * 1.0  # = params(prep, n_slots, lam): only the budget weight differs
        total = 0
        while True:
            z, _, done = kernel.minimise(z, iterations=s.iterations, damping=s.damping)
            total += done
            if not s.adaptive or lam >= s.lambda_max or passes(prep, z):
                break
            lam = min(2.0 * lam, s.lambda_max)
            kernel.p[:] = self.params(prep, n_slots, lam)
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
            return dataclasses.replace(plan, passed=True)
        for theta in np.arange(0.9, 0.05, -0.1):
            if passes(prep, theta * plan.z):
                return Iterate(theta * plan.z, f"solved_shortened(theta={theta:.1f})",
                               plan.iterations, plan.multiplier, passed=True)
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
