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
banded Cholesky solve (LAPACK ``pbtrs`` through :func:`scipy.linalg.solveh_banded`) and the
Sherman-Morrison formula. For a batch, the bands of all problems form one block-diagonal band
matrix: a single CasADi call and a single LAPACK call per iteration for every problem.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.linalg as sla

from solvers.planner.problem import GPPrior

_DISTANCE_EPS = 1e-12
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

    ``p = [g (2), centres (2 n_slots, row-major), clearances (n_slots), lambda, lambda_budget]``;
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
    p = ca.SX.sym("p", 4 + 3 * n_slots)
    goal = p[0:2]
    lam = p[2 + 3 * n_slots]
    lam_budget = p[3 + 3 * n_slots]
    positions = [ca.vertcat(0.0, 0.0)] + [z[2 * i : 2 * i + 2] for i in range(n)]
    smooth_res = ca.mtimes(ca.DM(prior.W), z)
    h = ca.sumsqr(smooth_res)
    residuals = [positions[-1] - goal, np.sqrt(weights.smooth_regulariser) * smooth_res]
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
        self._step_buf, self._step_eval = step.buffer()
        for k, arr in enumerate((self.w, self.p)):
            self._step_buf.set_arg(k, memoryview(arr))
        for k, arr in enumerate((self.f, self.g, self.band, self.a)):
            self._step_buf.set_res(k, memoryview(arr))
        self._cost_buf, self._cost_eval = cost.buffer()
        self._cost_buf.set_arg(0, memoryview(self.wc))
        self._cost_buf.set_arg(1, memoryview(self.p))
        self._cost_buf.set_res(0, memoryview(self.fc))
        self._maps: dict[int, MappedLMKernel] = {}

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
        solved = sla.solveh_banded(
            damped, np.column_stack([self.g, self.a]), lower=True, check_finite=False
        )
        u, v = solved[:, 0], solved[:, 1]
        step_w = -(u - v * (self.a @ u) / (1.0 + self.a @ v))
        return step_w[self.inverse]

    def mapped(self, batch: int) -> MappedLMKernel:
        """The functions mapped over ``batch`` problems (built once per size)."""
        if batch not in self._maps:
            self._maps[batch] = MappedLMKernel(self, batch)
        return self._maps[batch]


class MappedLMKernel:
    """:class:`LMKernel` for B problems: one CasADi call and one LAPACK call per iteration."""

    def __init__(self, kernel: LMKernel, batch: int) -> None:
        n_var = kernel.n_var
        self.batch = batch
        self.n_var = n_var
        self.perm = kernel.perm
        self.inverse = kernel.inverse
        # CasADi is column-major: a (B, n) C-order array is the n x B matrix of B columns.
        self.w = np.zeros((batch, n_var))
        self.p = np.zeros((batch, len(kernel.p)))
        self.f = np.zeros(batch)
        self.g = np.zeros((batch, n_var))
        self.band = np.zeros((batch, BANDWIDTH + 1, n_var))
        self.a = np.zeros((batch, n_var))
        self.wc = np.zeros((batch, n_var))
        self.fc = np.zeros(batch)
        self._step_buf, self._step_eval = kernel.step.map(batch).buffer()
        for k, arr in enumerate((self.w, self.p)):
            self._step_buf.set_arg(k, memoryview(arr))
        for k, arr in enumerate((self.f, self.g, self.band, self.a)):
            self._step_buf.set_res(k, memoryview(arr))
        self._cost_buf, self._cost_eval = kernel.cost.map(batch).buffer()
        self._cost_buf.set_arg(0, memoryview(self.wc))
        self._cost_buf.set_arg(1, memoryview(self.p))
        self._cost_buf.set_res(0, memoryview(self.fc))

    def evaluate(self, z: np.ndarray) -> np.ndarray:
        """Evaluate all problems at ``z`` (B, n); return the costs (B,)."""
        self.w[:] = z[:, self.perm]
        self._step_eval()
        return self.f.copy()

    def costs_at(self, z: np.ndarray) -> np.ndarray:
        """Penalty costs (B,) at ``z`` (B, n)."""
        self.wc[:] = z[:, self.perm]
        self._cost_eval()
        return self.fc.copy()

    def directions(self, mu: np.ndarray) -> np.ndarray:
        """Damped steps (B, n) for all problems: the band matrices stacked block-diagonally."""
        damped = self.band.copy()
        diag = damped[:, 0] + self.a**2
        damped[:, 0] += mu[:, None] * np.maximum(diag, 1e-9) + 1e-12
        big = damped.transpose(1, 0, 2).reshape(BANDWIDTH + 1, -1)
        rhs = np.column_stack([self.g.ravel(), self.a.ravel()])
        solved = sla.solveh_banded(big, rhs, lower=True, check_finite=False)
        u = solved[:, 0].reshape(self.batch, self.n_var)
        v = solved[:, 1].reshape(self.batch, self.n_var)
        au = np.einsum("bn,bn->b", self.a, u)
        av = np.einsum("bn,bn->b", self.a, v)
        step_w = -(u - v * (au / (1.0 + av))[:, None])
        return step_w[:, self.inverse]


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


def batch_levenberg_marquardt(
    kernel: MappedLMKernel,
    single: LMKernel,
    z0: np.ndarray,
    running: np.ndarray,
    *,
    iterations: int,
    damping: float,
    backtracks: int = 8,
    min_running_share: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`levenberg_marquardt` on the ``running`` problems of a batch, in lockstep.

    Every problem follows exactly the iteration it would follow alone (same steps, same
    acceptance), so the batch and a loop of single solves agree. The expensive parts are shared:
    one mapped CasADi call evaluates the Jacobian products of all problems and one banded LAPACK
    call solves all damped systems; the cheap cost evaluations of the line search run only for
    the problems that still need them (through ``single``, the unmapped kernel). Once fewer than
    ``min_running_share`` of the batch still iterate, the stragglers finish one by one (a mapped
    call would evaluate the finished problems too). Returns (z, iterations per problem).
    """
    z = z0.copy()
    running = running.copy()
    counts = np.zeros(len(z), dtype=int)
    cost = kernel.evaluate(z)
    mu = np.full(len(z), damping)

    def cost_of(b: int, point: np.ndarray) -> float:
        single.p[:] = kernel.p[b]
        return single.cost_at(point)

    done = 0
    for done in range(iterations):  # noqa: B007 (used after the loop)
        if running.sum() < max(min_running_share * len(z), 1):
            break
        counts[running] += 1
        try:
            directions = kernel.directions(mu)
        except np.linalg.LinAlgError:  # some block is not positive definite: go one by one
            directions = np.zeros_like(z)
            for b in np.flatnonzero(running):
                one = _single_direction(kernel, b, mu[b])
                if one is None:
                    mu[b] *= 10.0
                else:
                    directions[b] = one
        accepted = np.zeros(len(z), dtype=bool)
        full = np.zeros(len(z), dtype=bool)
        improvement = np.zeros(len(z))
        for b in np.flatnonzero(running):
            scale = 1.0
            for _ in range(backtracks + 1):
                trial = cost_of(b, z[b] + scale * directions[b])
                if trial < cost[b]:
                    accepted[b] = True
                    full[b] = scale == 1.0
                    improvement[b] = cost[b] - trial
                    z[b] = z[b] + scale * directions[b]
                    break
                scale *= 0.5
        mu[running & ~accepted] *= 16.0
        mu[full] = np.maximum(mu[full] / 3.0, 1e-12)
        mu[accepted & ~full] *= 4.0
        if accepted.any():
            evaluated = kernel.evaluate(z)
            cost[accepted] = evaluated[accepted]
        converged = accepted & ((improvement <= 1e-12 * np.maximum(cost, 1.0)) | (cost <= 1e-24))
        running &= ~converged & (mu <= 1e12)
    else:
        done = iterations
    for b in np.flatnonzero(running):
        single.p[:] = kernel.p[b]
        z[b], _, extra = levenberg_marquardt(
            single, z[b], iterations=iterations - done, damping=float(mu[b]), backtracks=backtracks
        )
        counts[b] += extra
    return z, counts


def _single_direction(kernel: MappedLMKernel, b: int, mu: float) -> np.ndarray | None:
    damped = kernel.band[b].copy()
    diag = damped[0] + kernel.a[b] ** 2
    damped[0] += mu * np.maximum(diag, 1e-9) + 1e-12
    try:
        solved = sla.solveh_banded(
            damped, np.column_stack([kernel.g[b], kernel.a[b]]), lower=True, check_finite=False
        )
    except np.linalg.LinAlgError:
        return None
    u, v = solved[:, 0], solved[:, 1]
    a = kernel.a[b]
    return -(u - v * (a @ u) / (1.0 + a @ v))[kernel.inverse]
