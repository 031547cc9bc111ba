"""The planning problem of thesis Eqs. 3.3-3.7 in a start-relative frame (§3.5.2).

Decision variables are the waypoints ``x_2..x_N`` and velocities ``v_2..v_N``; the first waypoint
is pinned to the start and the first velocity to zero (``h_init <= sigma_init`` with
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

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

#: Escape mode: a waypoint may be at most this much (m) closer to a violated obstacle than the
#: start is (the solvers are asked for a tenth of it, so their tolerances fit in between).
ESCAPE_TOLERANCE = 1e-6


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


@dataclass
class PreparedProblem:
    """One validated problem in the start-relative frame, ready for a backend.

    Attributes:
        start: Start s in world coordinates (2,).
        goal: Subgoal minus start (2,).
        centres: All obstacle centres minus start (m, 2).
        clearances: Required clearance ``eps' + r_j`` per obstacle (m,).
        selected: Indices into ``centres`` of the obstacles given to the backend (reachable ones,
            nearest first, at most ``max_obstacles``).
        escape: Boolean per obstacle: the start is inside its clearance (escape mode).
        required: Clearance each waypoint must keep per obstacle: ``clearances``, or the start's
            own distance (less ``ESCAPE_TOLERANCE``) for escape obstacles ("do not get closer").
    """

    start: np.ndarray
    goal: np.ndarray
    centres: np.ndarray
    clearances: np.ndarray
    selected: np.ndarray
    escape: np.ndarray
    required: np.ndarray
    start_distances: np.ndarray

    @property
    def escape_mode(self) -> bool:
        """True when the start violates the clearance of at least one obstacle."""
        return bool(self.escape.any())


def validate_point(name: str, value: object) -> np.ndarray:
    """Return ``value`` as a finite float array of shape (2,) or raise ValueError."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be a 2-vector of numbers, got {value!r}") from error
    if array.shape != (2,):
        raise ValueError(f"{name} must have shape (2,), got shape {array.shape}: {value!r}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    return array


def validate_obstacles(obstacles: object) -> tuple[np.ndarray, np.ndarray]:
    """Centres (m, 2) and radii (m,) from an (m, 2) or (m, 3) array-like; raise ValueError."""
    if obstacles is None:
        return np.zeros((0, 2)), np.zeros(0)
    try:
        array = np.asarray(obstacles, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"obstacles must be an (m, 2) array of centres or (m, 3) of [x, y, radius], "
            f"got {obstacles!r}"
        ) from error
    if array.size == 0:
        return np.zeros((0, 2)), np.zeros(0)
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise ValueError(
            "obstacles must have shape (m, 2) (centres) or (m, 3) (centres and radii), "
            f"got shape {array.shape}"
        )
    if not np.all(np.isfinite(array)):
        raise ValueError(f"obstacles must be finite, got {array.tolist()}")
    radii = array[:, 2].copy() if array.shape[1] == 3 else np.zeros(len(array))
    if np.any(radii < 0):
        raise ValueError(f"obstacle radii must be >= 0, got {radii.tolist()}")
    return array[:, :2].copy(), radii


def prepare(
    start: object,
    subgoal: object,
    obstacles: object,
    *,
    clearance: float,
    reach: float,
    max_obstacles: int,
) -> PreparedProblem:
    """Validate the inputs and select the obstacles a backend has to consider.

    Obstacles whose clearance disc lies beyond ``reach`` (the farthest any admissible waypoint can
    get from the start) are dropped; of the rest, the ``max_obstacles`` nearest (by distance minus
    clearance) are kept. The certificate still checks every obstacle given.
    """
    start_arr = validate_point("start", start)
    goal_arr = validate_point("subgoal", subgoal) - start_arr
    centres, radii = validate_obstacles(obstacles)
    centres = centres - start_arr
    clearances = clearance + radii
    start_distances = np.sqrt(np.einsum("mk,mk->m", centres, centres))
    gaps = start_distances - clearances
    escape = gaps < 0.0
    candidates = np.flatnonzero(gaps <= reach)
    order = candidates[np.argsort(gaps[candidates], kind="stable")]
    selected = order[:max_obstacles]
    required = np.where(escape, start_distances - ESCAPE_TOLERANCE, clearances)
    return PreparedProblem(
        start_arr, goal_arr, centres, clearances, selected, escape, required, start_distances
    )


def bucket_size(count: int, max_obstacles: int) -> int:
    """Compiled obstacle-slot count for ``count`` obstacles: 0 or the next power of two (capped)."""
    if count <= 0:
        return 0
    return min(max_obstacles, 1 << math.ceil(math.log2(count)))


def detour_guess(
    prior: GPPrior,
    goal: np.ndarray,
    centres: np.ndarray,
    clearances: np.ndarray,
    *,
    reach: float,
    inflate: float = 1.15,
) -> np.ndarray:
    """Initial guess: the smoothest trajectory to the goal (clipped to ``reach``), bent around
    the obstacles it crosses.

    For every obstacle whose (inflated) clearance disc the straight line crosses, the waypoint of
    the straight profile nearest to the centre becomes a via-point pushed perpendicular to the
    line, to the side away from the centre (to the left when the centre lies exactly on the line,
    so symmetric scenes still get a side to pass on). The guess is the smoothest trajectory (least
    ``h_smooth``) through the via-points and the target: one small linear solve.
    """
    distance = float(np.hypot(goal[0], goal[1]))
    target = goal if distance <= reach else goal * (reach / distance)
    z = prior.goal_map @ target
    if len(centres) == 0 or distance == 0.0:
        return z
    n = prior.n_waypoints - 1
    positions = z[: 2 * n].reshape(n, 2)
    direction = target / max(float(np.hypot(target[0], target[1])), 1e-12)
    perp = np.array([-direction[1], direction[0]])
    via_index: list[int] = []
    via_point: list[np.ndarray] = []
    for centre, radius in zip(centres, clearances, strict=True):
        rel = positions - centre
        dist = np.sqrt(np.einsum("nk,nk->n", rel, rel))
        k = int(np.argmin(dist))
        if dist[k] >= radius * inflate or k == n - 1 or k in via_index:
            continue
        offset = float(centre @ perp)
        side = -1.0 if offset > 0.0 else 1.0
        foot = centre + ((positions[k] - centre) @ direction) * direction
        via_index.append(k)
        via_point.append(foot + side * perp * radius * inflate)
    if not via_index:
        return z
    rows = [*via_index, n - 1]
    points = [*via_point, target]
    cols = np.ravel([[2 * k, 2 * k + 1] for k in rows])
    hessian_inv_select = prior.hessian_inv[:, cols]
    schur = hessian_inv_select[cols]
    # scipy's LAPACK, not numpy.linalg: numpy's threaded BLAS is slow on a busy 2-core machine
    return hessian_inv_select @ sla.solve(schur, np.concatenate(points), assume_a="pos")
