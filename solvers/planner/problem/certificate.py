"""The safety certificate: every returned plan keeps the clearance, or it is the stationary one.

Thesis §3.5.2: the stationary trajectory is feasible whenever the start is, so a plan that fails
the check of Eq. 3.7 (at the waypoints, or along every segment with the continuous option) is
replaced by it and flagged as a fallback. In escape mode (the start inside some clearance) the
check asks "no closer than the start" of those obstacles
(:func:`solvers.planner.problem.preparation.prepare`) and the plan aims at :func:`escape_target`
instead of the subgoal (docs/planner.md, "Backends"). A backend hands its plan over as an
:class:`Iterate`, whichever backend it is.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from solvers.planner.geometry import point_distances, segment_distances
from solvers.planner.problem.gp_prior import join, split
from solvers.planner.problem.preparation import PreparedProblem
from solvers.planner.result import PlanResult

#: Tolerance of the certificate (metres): a plan passes when every distance >= required - this.
CERTIFICATE_TOLERANCE = 1e-9


@dataclass
class Iterate:
    """A backend's plan before the certificate.

    Attributes:
        z: Trajectory variables in the start-relative frame (layout in
            :mod:`solvers.planner.problem.gp_prior`).
        status: Short text: ``solved``, ``max_iter``, ``solved_shortened(theta=0.8)`` ...
        iterations: Solver iterations (IPOPT iterations, LM iterations over every lambda round,
            or QP solves).
        multiplier: LM's penalty multiplier lambda (``nan`` for the other backends).
        failed: The backend raised; ``z`` is meaningless and the planner falls back.
        rescued: ``z`` is the rescue backend's plan, which passed the certificate.
        passed: the backend checked ``z`` with :meth:`Certificate.passes` and it held (the
            planner then does not check it again before deciding on a rescue).
    """

    z: np.ndarray
    status: str
    iterations: int
    multiplier: float = float("nan")
    failed: bool = False
    rescued: bool = False
    passed: bool = False


@dataclass(frozen=True)
class Certificate:
    """The check of a plan against every obstacle given (not only those the backend saw).

    Attributes:
        n_waypoints: N, waypoints including the start.
        clearance: eps' (m).
        continuous: Check the segments between waypoints too (exact segment distances).
        goal_tolerance: ``reached_subgoal`` is ``||x_N - subgoal|| < goal_tolerance``.
    """

    n_waypoints: int
    clearance: float
    continuous: bool
    goal_tolerance: float

    def passes(self, prep: PreparedProblem, z: np.ndarray) -> bool:
        """Each waypoint (segment) keeps its required distance to every obstacle."""
        if not np.isfinite(z).all():
            return False
        if len(prep.centres) == 0:
            return True
        positions, _ = split(z, self.n_waypoints)
        distances = (segment_distances(positions, prep.centres) if self.continuous
                     else point_distances(positions, prep.centres))
        return bool((distances >= prep.required[None, :] - CERTIFICATE_TOLERANCE).all())

    def clear_of(
        self, prep: PreparedProblem, z: np.ndarray, sel: np.ndarray, need: np.ndarray
    ) -> bool:
        """The waypoints after the start (all segments) keep ``need`` from the obstacles
        ``sel`` (no tolerance)."""
        if len(sel) == 0:
            return True
        positions, _ = split(z, self.n_waypoints)
        centres = prep.centres[sel]
        distances = (segment_distances(positions, centres) if self.continuous
                     else point_distances(positions[1:], centres))
        return bool(np.all(distances >= need[None, :]))

    def certify(
        self,
        prep: PreparedProblem,
        plan: Iterate,
        *,
        backend: str,
        tic: float,
        smoothness: Callable[[np.ndarray], float] | None = None,
        smoothness_budget: float = float("nan"),
    ) -> PlanResult:
        """Check the plan against every obstacle; replace it by the stationary one if it fails.

        Args:
            prep: The prepared problem.
            plan: The backend's (or the rescue's) iterate.
            backend: Name reported in the result.
            tic: ``time.perf_counter()`` at the start of the ``plan`` call.
            smoothness: ``h_smooth`` of trajectory variables (start-relative), reported for
                the returned plan with ``smoothness_budget`` (``nan`` without it).
        """
        z = plan.z
        status = plan.status
        fallback = plan.failed or not np.isfinite(z).all()
        if fallback:
            z = np.zeros(4 * (self.n_waypoints - 1))
            status = f"fallback: {plan.status}"
        positions, velocities = split(z, self.n_waypoints)
        radii = prep.clearances - self.clearance
        min_clear = min_cont = float("inf")
        feasible = True
        if len(prep.centres):
            point = point_distances(positions, prep.centres)
            segment = segment_distances(positions, prep.centres)
            checked = segment if self.continuous else point
            floor = CERTIFICATE_TOLERANCE
            if not fallback and not (checked >= prep.required[None, :] - floor).all():
                fallback = True
                status = f"fallback: {plan.status}: plan failed the clearance certificate"
                positions[:] = 0.0
                velocities[:] = 0.0
                point = np.broadcast_to(prep.start_distances, point.shape)
                segment = np.broadcast_to(prep.start_distances, segment.shape)
                checked = segment if self.continuous else point
            min_clear = float((point - radii[None, :]).min())
            min_cont = float((segment - radii[None, :]).min())
            feasible = bool((checked >= prep.clearances[None, :] - floor).all())
        gap = positions[-1] - prep.goal
        objective = float(gap @ gap)
        waypoints = positions + prep.start
        return PlanResult(
            waypoints=waypoints,
            velocities=velocities,
            feasible=feasible,
            status=status,
            fallback=fallback,
            escape_mode=prep.escape_mode,
            objective=objective,
            min_clearance=min_clear,
            min_clearance_continuous=min_cont,
            iterations=int(plan.iterations),
            solve_time_s=time.perf_counter() - tic,
            backend=backend,
            reached_subgoal=bool(np.sqrt(objective) < self.goal_tolerance),
            multiplier=float(plan.multiplier),
            n_considered=len(prep.selected),
            rescued=plan.rescued and not fallback,
            smoothness=(float("nan") if smoothness is None
                        else smoothness(join(waypoints - prep.start, velocities))),
            smoothness_budget=smoothness_budget,
        )


def escape_target(prep: PreparedProblem) -> np.ndarray:
    """Escape mode's target (start-relative): 0.1 m outside the violated clearances.

    The direction is the sum of the outward directions from the violated obstacles' centres,
    weighted by how deep the start is inside each; when they cancel (a start between two
    obstacles) it is perpendicular to the first one's, and (1, 0) at an exact centre.
    """
    violated = np.flatnonzero(prep.escape)
    depth = prep.clearances[violated] - prep.start_distances[violated]
    outward = -prep.centres[violated]
    norms = np.hypot(outward[:, 0], outward[:, 1])
    units = np.where(norms[:, None] > 1e-9, outward / np.maximum(norms, 1e-9)[:, None],
                     np.array([1.0, 0.0]))
    direction = (units * depth[:, None]).sum(axis=0)
    if np.hypot(*direction) < 1e-6 * max(float(depth.max()), 1e-9):
        direction = np.array([-units[0, 1], units[0, 0]])
    return direction / np.hypot(*direction) * (float(depth.max()) + 0.1)
