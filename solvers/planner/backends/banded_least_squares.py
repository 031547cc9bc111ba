"""Levenberg-Marquardt for least squares whose Gauss-Newton matrix is a band plus rank one.

The solver behind :mod:`solvers.planner.backends.lm` (App. B.2.3), apart from the residuals it
minimises: :class:`BandedKernel` evaluates compiled CasADi functions for the cost, ``J^T r``,
the band of ``J^T J`` and the rank-one term ``a a^T``, and takes a damped step with one banded
Cholesky solve (LAPACK ``dpbsv``) and the Sherman-Morrison formula; :func:`levenberg_marquardt`
is the monotone iteration around it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.linalg import lapack

(_pbsv,) = lapack.get_lapack_funcs(("pbsv",), (np.zeros(1),))


class BandedKernel:
    """A least-squares problem's compiled functions, evaluated through zero-copy buffers.

    ``step(w, p) -> (F, J^T r, band, a)`` and ``cost(w, p) -> F`` for ``F = ||r||^2``, where
    ``J^T J`` is the band matrix given by its lower diagonals (``band[i, d] = (J^T J)[i + d, i]``,
    shape ``(n, bandwidth + 1)``) plus ``a a^T``. The variables are ``w = z[perm]`` (``perm``
    orders them so that the band is narrow); the interface takes and returns ``z``. Set the
    parameters in :attr:`p` before evaluating.
    """

    def __init__(self, step: ca.Function, cost: ca.Function, perm: np.ndarray) -> None:
        self.step = step
        self.cost = cost
        self.perm = perm
        self.inverse = np.argsort(self.perm)
        n_var = len(self.perm)
        self.n_var = n_var
        self.p = np.zeros(step.size1_in(1))
        self.w = np.zeros(n_var)
        self.f = np.zeros(1)
        self.g = np.zeros(n_var)
        self.band = np.zeros((step.size2_out(2), n_var))  # CasADi's (n, b + 1) column-major
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

    def minimise(self, z0: np.ndarray, *, iterations: int, damping: float,
                 backtracks: int = 8) -> tuple[np.ndarray, float, int]:
        """:func:`levenberg_marquardt` on this kernel (its parameters already set)."""
        return levenberg_marquardt(self, z0, iterations=iterations, damping=damping,
                                   backtracks=backtracks)

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
    kernel: BandedKernel,
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
