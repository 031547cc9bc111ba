"""Levenberg-Marquardt backend: the thesis' penalty/dual form (Eq. 3.8, App. B.2.3).

For a multiplier ``lambda`` (one value for all constraints, App. B.2.3) the inner problem is the
nonlinear least-squares problem with residuals

* ``x_N - g`` (the objective f_goal, Eq. 3.4),
* ``sqrt(rho) W z`` (a small smoothness regulariser, also in the other backends' objective),
* ``sqrt(lambda w_smooth) (sqrt(h_smooth / sigma_smooth) - 1)_+`` (the smoothness budget,
  Eq. 3.6; the square root makes the residual a norm, which Gauss-Newton linearises well),
* ``sqrt(lambda w_obstacle) (c_j - d_ij)_+`` (the hinge of Eq. 3.7; with the continuous option
  ``d_ij`` is the distance of segment ``[x_i, x_{i+1}]`` to obstacle j).

The start constraint (Eq. 3.5) is exact: ``x_1`` and ``v_1`` are not variables.

Structure: with the variables ordered waypoint by waypoint (``[x_i, v_i]``, the "w" order), every
residual except the budget touches two consecutive waypoints, so ``J^T J`` is a band matrix
(bandwidth 7) plus the rank-one budget term ``a a^T``. One CasADi SX function per compiled
obstacle-slot count returns the cost, ``J^T r``, the band and ``a``; a damped step is then one
banded Cholesky solve (LAPACK ``dpbsv``) and the
Sherman-Morrison formula.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.linalg import lapack

from solvers.planner.problem import GPPrior

_DISTANCE_EPS = 1e-12
(_pbsv,) = lapack.get_lapack_funcs(("pbsv",), (np.zeros(1),))
#: Lower bandwidth of ``J^T J`` without the budget row in the w order (two waypoints x 4 - 1).
BANDWIDTH = 7


@dataclass(frozen=True)
class LMWeights:
    """Base penalty weights (multiplied by lambda) and the smoothness regulariser rho."""

    smooth_regulariser: float
    smooth_budget: float
    obstacle: float
    sigma_smooth: float


def w_order(n_waypoints: int) -> np.ndarray:
    """Permutation ``perm`` with ``w = z[perm]`` (z: positions then velocities; w: per waypoint)."""
    n = n_waypoints - 1
    perm = np.empty(4 * n, dtype=int)
    for i in range(n):
        perm[4 * i : 4 * i + 2] = [2 * i, 2 * i + 1]
        perm[4 * i + 2 : 4 * i + 4] = [2 * n + 2 * i, 2 * n + 2 * i + 1]
    return perm


def _segment_distance(a: ca.SX, b: ca.SX, centre: ca.SX) -> ca.SX:
    ab = b - a
    t = ca.dot(centre - a, ab) / (ca.dot(ab, ab) + _DISTANCE_EPS)
    t = ca.fmin(ca.fmax(t, 0.0), 1.0)
    diff = a + t * ab - centre
    return ca.sqrt(ca.dot(diff, diff) + _DISTANCE_EPS)


def build_lm_functions(
    prior: GPPrior, weights: LMWeights, n_slots: int, *, continuous: bool
) -> tuple[ca.Function, ca.Function]:
    """CasADi functions ``step(w, p) -> (F, J^T r, band, a)`` and ``cost(w, p) -> F``.

    ``w`` is the trajectory in the w order (:func:`w_order`). ``band`` is ``(n, 8)`` with
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
        np.sqrt(weights.smooth_regulariser) * smooth_res,
    ]
    obstacle_scale = ca.sqrt(lam * weights.obstacle)
    for j in range(n_slots):
        centre = p[2 + 2 * j : 4 + 2 * j]
        radius = p[2 + 2 * n_slots + j]
        for i in range(1, n + 1):
            if continuous:
                distance = _segment_distance(positions[i - 1], positions[i], centre)
            else:
                diff = positions[i] - centre
                distance = ca.sqrt(ca.dot(diff, diff) + _DISTANCE_EPS)
            residuals.append(obstacle_scale * ca.fmax(0.0, radius - distance))
    r_band = ca.vertcat(*residuals)
    r_budget = ca.sqrt(lam_budget * weights.smooth_budget) * ca.fmax(
        0.0, ca.sqrt(h + _DISTANCE_EPS) / np.sqrt(weights.sigma_smooth) - 1.0
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


class LMKernel:
    """The compiled functions of one slot count, evaluated through zero-copy buffers.

    The interface takes and returns trajectories in the z order; the w order stays inside.
    """

    def __init__(self, step: ca.Function, cost: ca.Function, n_waypoints: int) -> None:
        self.step = step
        self.cost = cost
        self.perm = w_order(n_waypoints)
        self.inverse = np.argsort(self.perm)
        n_var = len(self.perm)
        self.n_var = n_var
        self.p = np.zeros(step.size1_in(1))
        self.w = np.zeros(n_var)
        self.f = np.zeros(1)
        self.g = np.zeros(n_var)
        self.band = np.zeros((BANDWIDTH + 1, n_var))  # CasADi's (n, 8) column-major
        self.a = np.zeros(n_var)
        self.wc = np.zeros(n_var)
        self.fc = np.zeros(1)
        self._rhs = np.zeros((n_var, 2))
        self._step_buf, self._step_eval = step.buffer()
        for k, arr in enumerate((self.w, self.p)):
            self._step_buf.set_arg(k, memoryview(arr))
        for k, arr in enumerate((self.f, self.g, self.band, self.a)):
            self._step_buf.set_res(k, memoryview(arr))
        self._cost_buf, self._cost_eval = cost.buffer()
        self._cost_buf.set_arg(0, memoryview(self.wc))
        self._cost_buf.set_arg(1, memoryview(self.p))
        self._cost_buf.set_res(0, memoryview(self.fc))

    def evaluate(self, z: np.ndarray) -> float:
        """Evaluate cost, gradient and the Gauss-Newton matrix at ``z``; return the cost."""
        self.w[:] = z[self.perm]
        self._step_eval()
        return float(self.f[0])

    def cost_at(self, z: np.ndarray) -> float:
        """The penalty cost at ``z``."""
        self.wc[:] = z[self.perm]
        self._cost_eval()
        return float(self.fc[0])

    def direction(self, mu: float) -> np.ndarray:
        """Damped Gauss-Newton step ``-(J^T J + mu D)^{-1} J^T r`` at the last evaluation.

        ``D = diag(J^T J)`` (Marquardt scaling, floored at 1e-9). Raises LinAlgError when the
        damped band matrix is not positive definite.
        """
        damped = self.band.copy()
        diag = damped[0] + self.a**2
        damped[0] += mu * np.maximum(diag, 1e-9) + 1e-12
        self._rhs[:, 0] = self.g
        self._rhs[:, 1] = self.a
        # LAPACK dpbsv directly (banded Cholesky): scipy's solveh_banded adds ~5 us of checks
        _, solved, info = _pbsv(damped, self._rhs, lower=1, overwrite_ab=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"damped matrix is not positive definite (info={info})")
        u, v = solved[:, 0], solved[:, 1]
        step_w = -(u - v * (self.a @ u) / (1.0 + self.a @ v))
        return step_w[self.inverse]


def levenberg_marquardt(
    kernel: LMKernel,
    z0: np.ndarray,
    *,
    iterations: int,
    damping: float,
    backtracks: int = 8,
) -> tuple[np.ndarray, float, int]:
    """Monotone Levenberg-Marquardt on a kernel whose parameters are already set.

    A step is accepted only when it lowers the penalty cost, so the cost never exceeds its value
    at ``z0``. When the full step fails (the hinges switch on and off, so the Gauss-Newton model
    can be poor far away) the same direction is halved up to ``backtracks`` times (a cost
    evaluation each, cheap next to a Jacobian) and the damping is raised for the next iteration;
    after a full step the damping is divided by 3. Returns (z, cost, iterations).
    """
    z = z0.copy()
    cost = kernel.evaluate(z)
    mu = damping
    done = 0
    for done in range(1, iterations + 1):  # noqa: B007 (the count is returned)
        try:
            direction = kernel.direction(mu)
        except np.linalg.LinAlgError:
            mu *= 10.0
            continue
        scale = 1.0
        accepted = False
        for _ in range(backtracks + 1):
            new_cost = kernel.cost_at(z + scale * direction)
            if new_cost < cost:
                accepted = True
                break
            scale *= 0.5
        if not accepted:
            mu *= 16.0
            if mu > 1e12:
                break
            continue
        improvement = cost - new_cost
        z = z + scale * direction
        cost = kernel.evaluate(z)
        mu = max(mu / 3.0, 1e-12) if scale == 1.0 else mu * 4.0
        if improvement <= 1e-12 * max(cost, 1.0) or cost <= 1e-24:
            break
    return z, cost, done
