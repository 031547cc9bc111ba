"""The SCP backend: sequential convex programming on OSQP (the TrajOpt idea) for Eq. 3.3.

Each iteration solves the convex QP

    min ||x_N - g||^2 + rho ||W z||^2
    s.t. n_ij^T (x_i - o_j) >= c_j + delta          (tangent half-space of every active pair)
         grad h(z_k)^T (z - z_k) <= sigma - h(z_k)   (linearised smoothness budget)
         |z - z_k| <= trust                          (trust region)

where ``n_ij`` is the unit vector from obstacle j to waypoint i at the current iterate ``z_k`` (or,
with the continuous option, to the closest point of segment ``[x_i, x_{i+1}]``, and the half-space
is imposed on both of its ends). A half-space ``n^T (x - o) >= c`` with unit ``n`` lies outside the
disc of radius c, and the current iterate satisfies it, so the constraints are a conservative
inner approximation: starting from a feasible trajectory (the stationary one always is), every
QP solution keeps every waypoint (every segment) clear. The budget is convex, so the exact ``h`` on
the segment from ``z_k`` to the QP solution is a quadratic in the step length and the step is cut
back in closed form to keep ``h <= sigma``; the segment stays inside the half-spaces. The solver
is therefore safe whenever it is stopped. The objective is convex quadratic with a constant
Hessian (the GP prior stays quadratic), which avoids the indefinite Lagrangian Hessian that made
CasADi's ``sqpmethod`` fail on this problem. OSQP is set up once per compiled slot count and
updated and warm-started in place.

Every QP solution keeps every waypoint clear when the start iterate does, so the backend starts
from the previous plan or the detour guess (scaled into the smoothness budget) when that is clear
of the selected obstacles, and from the stationary trajectory otherwise. The knobs are those of
:class:`SCPSettings` (``conf/planner/scp.yaml``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import osqp
import scipy.sparse as sp

from solvers.planner.backends.base import bucket_size, hard_constraint_reach
from solvers.planner.geometry import length, point_offsets, segment_offsets
from solvers.planner.problem.certificate import Iterate
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.preparation import PreparedProblem
from solvers.planner.validation import count, positive, set_field

#: OSQP settings; every QP solution is re-checked exactly (and cut back), so a loose or
#: unfinished QP solve costs progress, never safety.
OSQP_SETTINGS: dict[str, object] = {
    "verbose": False,
    "eps_abs": 1e-5,
    "eps_rel": 1e-5,
    "max_iter": 200,
    "polishing": False,
    "warm_starting": True,
    "adaptive_rho": True,
}


@dataclass(frozen=True)
class SCPSettings:
    """The SCP backend's knobs, validated (``ValueError`` names the key and the value).

    Attributes:
        max_iterations: QP solves at most.
        trust_region: Half-width of the box trust region on every variable.
    """

    name: ClassVar[str] = "scp"

    max_iterations: int = 30
    trust_region: float = 1.0

    def __post_init__(self) -> None:
        set_field(self, "max_iterations", count("max_iterations", self.max_iterations, 1))
        set_field(self, "trust_region", positive("trust_region", self.trust_region))

    def build(self, context: ProblemContext) -> ScpBackend:
        """The SCP backend for ``context``'s problem."""
        return ScpBackend(context, self)


@dataclass
class ScpOutcome:
    """Raw SCP result (start-relative ``z``)."""

    z: np.ndarray
    status: str
    iterations: int
    converged: bool


class ScpProgram:
    """One OSQP problem with a fixed sparsity pattern for ``n_slots`` obstacle slots."""

    def __init__(
        self,
        prior: GPPrior,
        n_slots: int,
        *,
        smooth_regulariser: float,
        continuous: bool,
        settings: dict[str, object] | None = None,
    ) -> None:
        self.prior = prior
        self.smooth_regulariser = smooth_regulariser
        self.n_slots = n_slots
        self.continuous = continuous
        n = prior.n_waypoints - 1
        self.n = n
        nv = prior.n_var
        goal_select = np.zeros((2, nv))
        goal_select[0, 2 * (n - 1)] = goal_select[1, 2 * (n - 1) + 1] = 1.0
        self.goal_select = goal_select
        hessian = 2.0 * (goal_select.T @ goal_select + smooth_regulariser * prior.hessian)
        self.P = sp.triu(sp.csc_matrix(hessian), format="csc")
        # Constraint rows: trust region (nv), budget (1), obstacle rows.
        rows: list[int] = list(range(nv))
        cols: list[int] = list(range(nv))
        rows += [nv] * nv
        cols += list(range(nv))
        self.n_obstacle_rows = n_slots * n * (2 if continuous else 1)
        base = nv + 1
        for j in range(n_slots):
            for i in range(n):
                if continuous:
                    # segment i joins waypoint i (0 = pinned start) and waypoint i + 1
                    r_a = base + (j * n + i) * 2
                    if i > 0:
                        rows += [r_a, r_a]
                        cols += [2 * (i - 1), 2 * (i - 1) + 1]
                    rows += [r_a + 1, r_a + 1]
                    cols += [2 * i, 2 * i + 1]
                else:
                    r = base + j * n + i
                    rows += [r, r]
                    cols += [2 * i, 2 * i + 1]
        self.n_rows = base + self.n_obstacle_rows
        order = np.arange(1, len(rows) + 1, dtype=float)
        pattern = sp.csc_matrix((order, (rows, cols)), shape=(self.n_rows, nv))
        pattern.sort_indices()
        self.perm = pattern.data.astype(int) - 1  # data[k] = values[perm[k]]
        self.values = np.ones(len(rows))
        self.values[nv : 2 * nv] = 0.0
        self.A = sp.csc_matrix((self.values[self.perm], pattern.indices, pattern.indptr),
                               shape=pattern.shape)
        self.lower = np.full(self.n_rows, -np.inf)
        self.upper = np.full(self.n_rows, np.inf)
        self.solver = osqp.OSQP()
        options = dict(settings or OSQP_SETTINGS)
        self._rho = float(options.setdefault("rho", 0.1))
        self.solver.setup(self.P, np.zeros(nv), self.A, self.lower, self.upper, **options)

    def _normals(
        self, positions: np.ndarray, centres: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Unit normals (m, n, 2) and current distances (m, n) per (obstacle, waypoint/segment)."""
        dx, dy = (segment_offsets(positions, centres) if self.continuous
                  else point_offsets(positions[1:], centres))
        dist = length(dx, dy).T
        normals = np.stack((dx.T, dy.T), axis=-1) / np.maximum(dist, 1e-12)[..., None]
        return normals, dist

    def _clear(self, z: np.ndarray, centres: np.ndarray, need: np.ndarray) -> bool:
        positions = np.zeros((self.n + 1, 2))
        positions[1:] = z[: 2 * self.n].reshape(self.n, 2)
        _, dist = self._normals(positions, centres)
        return bool(np.all(dist >= need[:, None]))

    def solve(
        self,
        z0: np.ndarray,
        goal: np.ndarray,
        centres: np.ndarray,
        need: np.ndarray,
        *,
        sigma_smooth: float,
        trust_region: float,
        max_iterations: int,
        exact_need: np.ndarray | None = None,
        tolerance: float = 1e-7,
    ) -> ScpOutcome:
        """Run SCP from the feasible ``z0`` (every pair keeps ``need``; ``h(z0) <= sigma``).

        Args:
            z0: Feasible initial trajectory variables.
            goal: Start-relative target.
            centres: Selected obstacle centres (m <= n_slots, 2), start-relative.
            need: Distance each waypoint (segment) must keep from each selected obstacle.
            sigma_smooth: Smoothness budget.
            trust_region: Half-width of the box trust region on every variable.
            max_iterations: QP solves at most.
            exact_need: Distances the exact check enforces (default ``need``); QP solutions
                that violate them are cut back. Set it a little below ``need`` where ``need``
                includes a margin for OSQP's tolerance.
            tolerance: Stop when the step's infinity norm falls below this.
        """
        prior = self.prior
        nv = prior.n_var
        n = self.n
        m = len(centres)
        W = prior.W
        q = -2.0 * (self.goal_select.T @ goal)
        self.solver.update(q=q)
        z = z0.copy()

        def objective(vec: np.ndarray) -> float:
            r = W @ vec
            end = vec[2 * (n - 1) : 2 * n] - goal
            return float(end @ end + self.smooth_regulariser * (r @ r))

        current = objective(z)
        # every solve starts from the same state (duals and OSQP's adaptive step size), so a
        # result does not depend on the problems solved before
        self._dual = np.zeros(self.n_rows)
        self.solver.update_settings(rho=self._rho)
        exact_need = need if exact_need is None else exact_need
        status = "max_iter"
        converged = False
        iterations = 0
        lower = self.lower
        upper = self.upper
        values = self.values
        base = nv + 1
        for iterations in range(1, max_iterations + 1):  # noqa: B007 (the count is returned)
            positions = np.zeros((n + 1, 2))
            positions[1:] = z[: 2 * n].reshape(n, 2)
            residual = W @ z
            h = float(residual @ residual)
            grad_h = 2.0 * (W.T @ residual)
            lower[:nv] = z - trust_region
            upper[:nv] = z + trust_region
            values[nv : 2 * nv] = grad_h
            upper[nv] = sigma_smooth - h + grad_h @ z
            if m:
                normals, _ = self._normals(positions, centres)
                rhs = need[:, None] + np.einsum("mnk,mk->mn", normals, centres)
                obstacle_values = np.zeros((self.n_slots, n, 2 if self.continuous else 1, 2))
                obstacle_lower = np.full((self.n_slots, n, 2 if self.continuous else 1), -np.inf)
                if self.continuous:
                    obstacle_values[:m, :, 0, :] = normals
                    obstacle_values[:m, :, 1, :] = normals
                    obstacle_lower[:m, :, 0] = rhs
                    obstacle_lower[:m, :, 1] = rhs
                    obstacle_lower[:, 0, 0] = -np.inf  # the pinned start is not a variable
                    flat = obstacle_values.reshape(self.n_slots, n, 2, 2)
                    # the pattern has no entries for the start row of segment 0
                    keep = np.ones((self.n_slots, n, 2), dtype=bool)
                    keep[:, 0, 0] = False
                    obstacle_flat = flat[keep].ravel()
                else:
                    obstacle_values[:m, :, 0, :] = normals
                    obstacle_lower[:m, :, 0] = rhs
                    obstacle_flat = obstacle_values.ravel()
                values[2 * nv :] = obstacle_flat
                lower[base:] = obstacle_lower.ravel()
            # normalise the budget row (its gradient can be large) for OSQP's conditioning
            scale_row = max(float(np.linalg.norm(grad_h)), 1e-12)
            values[nv : 2 * nv] /= scale_row
            upper[nv] /= scale_row
            self.solver.update(Ax=values[self.perm], l=lower, u=upper)
            self.solver.warm_start(x=z, y=self._dual)
            result = self.solver.solve(raise_error=False)
            if result.x is None or not np.all(np.isfinite(result.x)):
                status = f"qp_{result.info.status}"
                break
            self._dual = result.y
            step = result.x - z
            # exact budget: h(z + t step) = a t^2 + b t + h
            w_step = W @ step
            a = float(w_step @ w_step)
            b = 2.0 * float(residual @ w_step)
            t = 1.0
            if a * t * t + b * t + h > sigma_smooth and a > 0.0:
                disc = b * b - 4.0 * a * (h - sigma_smooth)
                t = max(0.0, min(1.0, (-b + np.sqrt(max(disc, 0.0))) / (2.0 * a)))
            # exact clearance (the QP is solved to a tolerance): cut the step back if needed
            for _ in range(12):
                if m == 0 or self._clear(z + t * step, centres, exact_need):
                    break
                t *= 0.5
            else:
                t = 0.0
            candidate = z + t * step
            value = objective(candidate)
            if t == 0.0 or value > current - 1e-12:
                status = "converged" if t > 0.0 else "stalled"
                converged = True
                break
            z = candidate
            improvement = current - value
            current = value
            if np.max(np.abs(t * step)) < tolerance or improvement < 1e-10 * max(current, 1e-3):
                status = "converged"
                converged = True
                break
        return ScpOutcome(z, status, iterations, converged)


class ScpBackend:
    """Solve the prepared problem by sequential convex programming (see the module docstring).

    Attributes:
        context: The problem's settings, prior and certificate.
        settings: The SCP knobs.
        selection_reach: Obstacles beyond this (m) are not given to SCP.
        programs: OSQP programs by obstacle-slot count; not pickled.
    """

    def __init__(self, context: ProblemContext, settings: SCPSettings) -> None:
        self.context = context
        self.settings = settings
        self.selection_reach = hard_constraint_reach(context)
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
        for slots in slot_counts:
            self.program(slots)

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
            trust_region=self.settings.trust_region,
            max_iterations=self.settings.max_iterations,
            exact_need=exact_need,
        )
        return Iterate(outcome.z, outcome.status, outcome.iterations)

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the OSQP programs; they are set up again lazily."""
        return {**self.__dict__, "programs": {}}
