"""The planner's result object: a plan and its safety certificate (thesis §3.5.2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlanResult:
    """A planned trajectory and its safety certificate.

    Attributes:
        waypoints: (N, 2) positions in world coordinates; ``waypoints[0]`` is the start.
        velocities: (N, 2) GP-prior velocities (``velocities[0] = 0``); the follower ignores them.
        feasible: Every waypoint (and, with ``continuous``, every segment) keeps the clearance
            ``eps' + r_j`` from every obstacle given, within 1e-9. False only in escape mode.
        status: Short text: ``solved``, ``max_iter`` ... or ``fallback: <reason>``.
        fallback: The backend's plan failed the certificate (or the backend failed) and the
            stationary trajectory (all waypoints at the start) was returned instead.
        escape_mode: The start was inside some obstacle's clearance; the plan only guarantees not
            getting closer to those obstacles than the start is (and full clearance from others).
        objective: ``||x_N - subgoal||^2`` (Eq. 3.4) of the returned plan.
        min_clearance: Smallest waypoint distance to an obstacle's surface (centre distance minus
            radius; compare with eps'); ``inf`` without obstacles.
        min_clearance_continuous: The same for the polyline's segments (exact segment-to-centre
            distance minus radius).
        iterations: Solver iterations (IPOPT iterations, LM iterations summed over lambda
            rounds, or QP solves).
        solve_time_s: Wall-clock seconds of the whole ``plan`` call.
        backend: ``ipopt``, ``lm`` or ``scp``.
        reached_subgoal: ``||x_N - subgoal|| < goal_tolerance``.
        multiplier: The LM penalty multiplier lambda of the returned plan (``nan`` for others).
        n_considered: Number of obstacles given to the backend (after dropping unreachable ones
            and keeping at most ``max_obstacles``); the certificate checks all of them.
        rescued: The backend's own plan failed the certificate and IPOPT's (``rescue_backend``)
            passed it; ``backend`` still names the primary backend.
        smoothness: ``h_smooth`` of the returned plan (Eq. 3.6).
        smoothness_budget: ``sigma_smooth``, the budget of Eq. 3.3 (``h_smooth <= sigma``): the
            IPOPT and SCP backends keep it as a constraint, the LM backend as a penalty (its
            plans may exceed it; the clearance certificate does not check it).
    """

    waypoints: np.ndarray
    velocities: np.ndarray
    feasible: bool
    status: str
    fallback: bool
    escape_mode: bool
    objective: float
    min_clearance: float
    min_clearance_continuous: float
    iterations: int
    solve_time_s: float
    backend: str
    reached_subgoal: bool
    multiplier: float = float("nan")
    n_considered: int = 0
    rescued: bool = False
    smoothness: float = float("nan")
    smoothness_budget: float = float("nan")

    @property
    def within_budget(self) -> bool:
        """``h_smooth <= sigma_smooth`` (relative tolerance 1e-6; true where a planner has no
        budget, ``nan``)."""
        return not self.smoothness > self.smoothness_budget * (1.0 + 1e-6)

    def summary(self) -> str:
        """A few human-readable lines (used by the CLI)."""
        lines = [
            f"backend={self.backend} status={self.status} feasible={self.feasible} "
            f"fallback={self.fallback} escape_mode={self.escape_mode} rescued={self.rescued}",
            f"objective={self.objective:.6g} reached_subgoal={self.reached_subgoal} "
            f"final_waypoint={np.round(self.waypoints[-1], 4).tolist()}",
            f"min_clearance waypoints={self.min_clearance:.6f} m "
            f"continuous={self.min_clearance_continuous:.6f} m",
            f"h_smooth={self.smoothness:.6g} budget sigma={self.smoothness_budget:.6g} "
            f"within_budget={self.within_budget}",
            f"iterations={self.iterations} solve_time={self.solve_time_s * 1e3:.2f} ms "
            f"obstacles_considered={self.n_considered}",
        ]
        return "\n".join(lines)
