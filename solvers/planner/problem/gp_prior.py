"""The trajectory variables and the smoothness prior h_smooth of thesis Eq. 3.6 (§3.5.2).

Decision variables are the waypoints ``x_2..x_N`` and velocities ``v_2..v_N``; the first waypoint
is pinned to the start and the first velocity to zero (Eq. 3.5, ``h_init <= sigma_init`` with
``sigma_init = 0``, the start velocity of the public code). Everything is solved in the frame
whose origin is the start, so the stationary trajectory is ``z = 0``.

Layout of the vector ``z`` (length ``4 (N - 1)``): positions ``x_2..x_N`` flattened row-major
(``[x_2x, x_2y, x_3x, ...]``), then velocities ``v_2..v_N`` in the same order.

The smoothness term (Eq. 3.6) is the constant-velocity GP prior of GPMP2 with ``Q_c = I``:
``h_smooth = sum_i e_i^T Q_i^{-1} e_i`` with ``e_i = [x_{i+1} - x_i - v_i dt; v_{i+1} - v_i]`` and
``Q_i^{-1} = [[12/dt^3, -6/dt^2], [-6/dt^2, 4/dt]] (x) I_2``. It is written as ``||W z||^2``
(``W`` is the stacked upper Cholesky factor applied to the linear map ``z -> e``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class GPPrior:
    """Constant-velocity GP prior of Eq. 3.6 for ``n_waypoints`` waypoints spaced ``dt`` apart.

    Attributes:
        n_waypoints: N, the number of waypoints including the pinned start.
        dt: Time between waypoints (s).
        W: Matrix with ``h_smooth(z) = ||W z||^2`` (start-relative frame, ``x_1 = 0, v_1 = 0``).
        hessian: ``W^T W``.
        goal_map: ``(4(N-1), 2)`` matrix: ``goal_map @ t`` is the smoothest trajectory whose last
            waypoint is ``t`` (minimum of ``h_smooth`` subject to ``x_N = t``).
        reach_coef: ``kappa_i`` with ``min h_smooth s.t. x_i = t`` equal to ``kappa_i ||t||^2``;
            shape (N,), ``kappa_1 = inf`` (the pinned start).
    """

    n_waypoints: int
    dt: float
    W: np.ndarray = field(repr=False)
    hessian: np.ndarray = field(repr=False)
    hessian_inv: np.ndarray = field(repr=False)
    goal_map: np.ndarray = field(repr=False)
    reach_coef: np.ndarray = field(repr=False)

    @property
    def n_var(self) -> int:
        """Number of decision variables ``4 (N - 1)``."""
        return 4 * (self.n_waypoints - 1)

    def smoothness(self, z: np.ndarray) -> float:
        """``h_smooth(z)`` of Eq. 3.6."""
        r = self.W @ z
        return float(r @ r)

    def reach_radii(self, sigma_smooth: float) -> np.ndarray:
        """Largest ``||x_i - s||`` any trajectory with ``h_smooth <= sigma_smooth`` can have."""
        with np.errstate(divide="ignore"):
            return np.sqrt(sigma_smooth / self.reach_coef)


def build_gp_prior(n_waypoints: int, dt: float) -> GPPrior:
    """Assemble the GP-prior matrices of Eq. 3.6 (see the module docstring)."""
    n = n_waypoints - 1
    n_var = 4 * n
    precision = np.array([[12.0 / dt**3, -6.0 / dt**2], [-6.0 / dt**2, 4.0 / dt]])
    upper = np.linalg.cholesky(precision).T  # precision = upper^T upper
    W = np.zeros((n_var, n_var))

    def pos(i: int, k: int) -> int | None:  # waypoint index i in 0..N-1 (0 = pinned start)
        return None if i == 0 else 2 * (i - 1) + k

    def vel(i: int, k: int) -> int | None:
        return None if i == 0 else 2 * n + 2 * (i - 1) + k

    row = 0
    for i in range(n):
        for k in range(2):
            e_pos = np.zeros(n_var)
            e_vel = np.zeros(n_var)
            for idx, coef, target in (
                (pos(i + 1, k), 1.0, e_pos),
                (pos(i, k), -1.0, e_pos),
                (vel(i, k), -dt, e_pos),
                (vel(i + 1, k), 1.0, e_vel),
                (vel(i, k), -1.0, e_vel),
            ):
                if idx is not None:
                    target[idx] += coef
            W[row] = upper[0, 0] * e_pos + upper[0, 1] * e_vel
            W[row + 1] = upper[1, 1] * e_vel
            row += 2
    hessian = W.T @ W
    hessian_inv = np.linalg.inv(hessian)
    reach = np.full(n_waypoints, np.inf)
    goal_map = np.zeros((n_var, 2))
    for i in range(1, n_waypoints):
        select = np.zeros((2, n_var))
        select[0, pos(i, 0)] = 1.0
        select[1, pos(i, 1)] = 1.0
        schur = select @ hessian_inv @ select.T  # isotropic: kappa^-1 I
        reach[i] = 1.0 / schur[0, 0]
        if i == n_waypoints - 1:
            goal_map = hessian_inv @ select.T @ np.linalg.inv(schur)
    return GPPrior(n_waypoints, dt, W, hessian, hessian_inv, goal_map, reach)


def split(z: np.ndarray, n_waypoints: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (each (N, 2), start-relative, first row pinned at 0) from ``z``."""
    n = n_waypoints - 1
    positions = np.zeros((n_waypoints, 2))
    velocities = np.zeros((n_waypoints, 2))
    positions[1:] = z[: 2 * n].reshape(n, 2)
    velocities[1:] = z[2 * n :].reshape(n, 2)
    return positions, velocities


def join(positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """Inverse of :func:`split` (drops the pinned first row)."""
    return np.concatenate([positions[1:].ravel(), velocities[1:].ravel()])
