"""The detour guess: an initial trajectory that already passes the obstacles (thesis §3.5.2).

The smoothest trajectory (least h_smooth, Eq. 3.6) to the goal, bent around the obstacles the
straight line crosses; the backends start from it (or from the previous plan).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from solvers.planner.geometry import point_distances
from solvers.planner.problem.gp_prior import GPPrior


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
    # every obstacle's distance to every waypoint at once; its nearest waypoint and that distance
    dist = point_distances(positions, np.asarray(centres)).T
    nearest = dist.argmin(axis=1)
    nearest_dist = dist[np.arange(len(nearest)), nearest]
    for centre, radius, k, d in zip(centres, clearances, nearest.tolist(),
                                    nearest_dist.tolist(), strict=True):
        if d >= radius * inflate or k == n - 1 or k in via_index:
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
    # LAPACK's dposv (Cholesky), the routine behind scipy.linalg.solve(assume_a="pos"), called
    # directly: the same floats without that function's checks and condition estimate (20 us
    # of a 1 us solve); scipy's LAPACK, as numpy's threaded BLAS is slow on a busy machine
    _, weights, info = lapack.dposv(schur, np.concatenate(points))
    if info != 0:
        raise np.linalg.LinAlgError(f"detour guess: via-point system not positive definite "
                                    f"(dposv info {info})")
    return hessian_inv_select @ weights
