"""Levenberg-Marquardt backend: the thesis' penalty/dual form (Eq. 3.8, App. B.2.3).

For a multiplier ``lambda`` (one value for all constraints, App. B.2.3) the inner problem is the
nonlinear least-squares problem with residuals

* ``x_N - g`` (the objective f_goal, Eq. 3.4),
* ``sqrt(rho) W z`` (a small smoothness regulariser, also in the other backends' objective),
* ``sqrt(lambda w_smooth) (sqrt(h_smooth / sigma_smooth) - 1)_+`` (the smoothness budget,
  Eq. 3.6; the square root makes the residual a norm, which Gauss-Newton linearises well),
* ``sqrt(lambda w_obstacle) (c_j - d_ij)_+`` (the hinge of Eq. 3.7; with the continuous option
  ``d_ij`` is the distance of segment ``[x_i, x_{i+1}]`` to obstacle j).

The start constraint (Eq. 3.5) is exact: ``x_1`` and ``v_1`` are not variables. Residuals, ``J^T r``
and ``J^T J`` come from one CasADi SX function per compiled obstacle-slot count (built once and
cached); the LM iteration itself (Marquardt damping, monotone step acceptance) is in
:mod:`solvers.planner.planner`.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from solvers.planner.problem import GPPrior

_DISTANCE_EPS = 1e-12


@dataclass(frozen=True)
class LMWeights:
    """Base penalty weights (multiplied by lambda) and the smoothness regulariser rho."""

    smooth_regulariser: float
    smooth_budget: float
    obstacle: float
    sigma_smooth: float


def _segment_distance(a: ca.SX, b: ca.SX, centre: ca.SX) -> ca.SX:
    ab = b - a
    t = ca.dot(centre - a, ab) / (ca.dot(ab, ab) + _DISTANCE_EPS)
    t = ca.fmin(ca.fmax(t, 0.0), 1.0)
    diff = a + t * ab - centre
    return ca.sqrt(ca.dot(diff, diff) + _DISTANCE_EPS)


def build_lm_functions(
    prior: GPPrior, weights: LMWeights, n_slots: int, *, continuous: bool
) -> tuple[ca.Function, ca.Function]:
    """CasADi functions ``step(z, p) -> (F, J^T r, J^T J)`` and ``cost(z, p) -> F``.

    ``p = [g (2), centres (2 n_slots, row-major), clearances (n_slots), lambda, lambda_budget]``;
    a clearance of 0 disables its slot (the hinge is then identically zero). The solve uses
    ``lambda_budget = lambda`` (one multiplier, App. B.2.3); a smaller value only serves to rank
    initial guesses.
    """
    n = prior.n_waypoints - 1
    z = ca.SX.sym("z", prior.n_var)
    p = ca.SX.sym("p", 4 + 3 * n_slots)
    goal = p[0:2]
    lam = p[2 + 3 * n_slots]
    lam_budget = p[3 + 3 * n_slots]
    positions = [ca.vertcat(0.0, 0.0)] + [z[2 * i : 2 * i + 2] for i in range(n)]
    smooth_res = ca.mtimes(ca.DM(prior.W), z)
    h = ca.sumsqr(smooth_res)
    residuals = [
        positions[-1] - goal,
        np.sqrt(weights.smooth_regulariser) * smooth_res,
        ca.sqrt(lam_budget * weights.smooth_budget)
        * ca.fmax(0.0, ca.sqrt(h + _DISTANCE_EPS) / np.sqrt(weights.sigma_smooth) - 1.0),
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
    r = ca.vertcat(*residuals)
    jac = ca.jacobian(r, z)
    cost = ca.sumsqr(r)
    step = ca.Function(
        f"lm_step_{n_slots}", [z, p], [cost, ca.mtimes(jac.T, r), ca.densify(ca.mtimes(jac.T, jac))]
    )
    cost_fn = ca.Function(f"lm_cost_{n_slots}", [z, p], [cost])
    return step, cost_fn
