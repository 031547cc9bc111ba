"""The IPOPT backend: Eq. 3.3 with hard pairwise clearance constraints (thesis §3.5.2).

``min ||x_N - g||^2 + rho h_smooth`` subject to ``h_smooth <= sigma_smooth`` and, per waypoint i
and obstacle j, ``||x_i - o_j||^2 >= (c_j + delta)^2`` (the aggregated hinge of Eq. 3.3 is
degenerate for an interior-point method: its value and gradient vanish on the whole feasible
set, so no constraint qualification holds). With the continuous option every
segment ``[x_i, x_{i+1}]`` and obstacle j get a separating direction ``n_ij`` (two extra variables)
with ``n_ij^T (x_i - o_j) >= c_j + delta``, ``n_ij^T (x_{i+1} - o_j) >= c_j + delta`` and
``||n_ij||^2 <= 1``, which holds iff the whole segment keeps the clearance.

One parametric ``nlpsol`` is built (SX) per compiled obstacle-slot count and attempt, and cached;
unused slots and pairs a waypoint cannot reach get infinite bounds, so the structure never
changes. Escape mode (start inside a clearance) relaxes those obstacles' rows to "no closer than
the start"; the planner then aims at a point outside them instead of the subgoal.

Two attempts: a short one from the detour guess (or the previous plan), kept when it passes the
certificate, then a cold one from the stationary trajectory, which is feasible whenever the start
is (thesis §3.5.2). A guess-only start was faster in the median but failed on 2-3 % of the tuning
problems (docs/planner.md, "Calibration"). Escape mode skips the first attempt. The knobs are
those of :class:`IpoptSettings` (``conf/planner/ipopt.yaml``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from solvers.planner.backends.base import bucket_size, hard_constraint_reach
from solvers.planner.geometry import (
    length,
    point_offset,
    segment_offsets,
    separation,
    squared_length,
    symbolic_offset,
)
from solvers.planner.problem.certificate import Iterate
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.preparation import PreparedProblem
from solvers.planner.validation import count, mapping, set_field

#: IPOPT options for re-solves from a good initial guess (docs/planner.md, "Calibration").
IPOPT_OPTIONS: dict[str, object] = {
    "print_level": 0,
    "sb": "yes",
    "linear_solver": "mumps",
    "tol": 1e-4,  # 9 instead of 13 median iterations, same plans; feasibility has its own tol
    "constr_viol_tol": 1e-7,
    "acceptable_tol": 1e-3,
    "acceptable_iter": 5,
    "max_iter": 200,
    "max_wall_time": 1.0,
    "mu_strategy": "monotone",
    "bound_push": 1e-6,
    "bound_frac": 1e-6,
    "slack_bound_push": 1e-6,
    "slack_bound_frac": 1e-6,
}


@dataclass(frozen=True)
class IpoptSettings:
    """The IPOPT backend's knobs, validated (``ValueError`` names the key and the value).

    Attributes:
        max_iter: Iteration cap of the cold attempt (from the stationary trajectory).
        first_max_iter: Iteration cap of the first attempt from the guess / previous plan
            (0: skip it).
        options: IPOPT options merged over :data:`IPOPT_OPTIONS` (None is stored as an empty
            dict; not part of the hash).
    """

    name: ClassVar[str] = "ipopt"

    max_iter: int = 200
    first_max_iter: int = 30
    options: Mapping[str, object] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        set_field(self, "max_iter", count("max_iter", self.max_iter, 1))
        set_field(self, "first_max_iter", count("first_max_iter", self.first_max_iter, 0))
        set_field(self, "options", mapping("options", self.options))

    def build(self, context: ProblemContext) -> IpoptBackend:
        """The IPOPT backend for ``context``'s problem."""
        return IpoptBackend(context, self)


@dataclass
class IpoptProgram:
    """A built IPOPT solver for ``n_slots`` obstacle slots."""

    solver: ca.Function
    n_slots: int
    continuous: bool
    n_var: int
    n_con: int


def build_ipopt(
    prior: GPPrior,
    n_slots: int,
    *,
    smooth_regulariser: float,
    continuous: bool,
    ipopt_options: dict[str, object],
) -> IpoptProgram:
    """Build the parametric NLP; ``p = [g (2), centres (2 n_slots, row-major)]``."""
    n = prior.n_waypoints - 1
    z = ca.SX.sym("z", prior.n_var)
    p = ca.SX.sym("p", 2 + 2 * n_slots)
    goal = p[0:2]
    positions = [ca.vertcat(0.0, 0.0)] + [z[2 * i : 2 * i + 2] for i in range(n)]
    h = ca.sumsqr(ca.mtimes(ca.DM(prior.W), z))
    objective = ca.sumsqr(positions[-1] - goal) + smooth_regulariser * h
    constraints = [h]
    normals: list[ca.SX] = []
    for j in range(n_slots):
        centre = p[2 + 2 * j : 4 + 2 * j]
        if not continuous:
            constraints.extend(squared_length(*symbolic_offset(positions[i], centre))
                               for i in range(1, n + 1))
        if continuous:
            for i in range(n):
                normal = ca.SX.sym(f"n_{j}_{i}", 2)
                normals.append(normal)
                for end in (i, i + 1):  # both ends of segment i
                    constraints.append(separation(normal, symbolic_offset(positions[end], centre)))
                constraints.append(squared_length(normal[0], normal[1]))
    x = ca.vertcat(z, *normals)
    g = ca.vertcat(*constraints)
    options = {"print_time": False, "ipopt": dict(ipopt_options)}
    solver = ca.nlpsol(
        f"planner_ipopt_{n_slots}{'_cont' if continuous else ''}",
        "ipopt",
        {"x": x, "p": p, "f": objective, "g": g},
        options,
    )
    return IpoptProgram(solver, n_slots, continuous, int(x.numel()), int(g.numel()))


@dataclass
class IpoptOutcome:
    """Raw IPOPT result (start-relative ``z``)."""

    z: np.ndarray
    status: str
    success: bool
    iterations: int


def solve_ipopt(
    program: IpoptProgram,
    prior: GPPrior,
    z0: np.ndarray,
    goal: np.ndarray,
    centres: np.ndarray,
    required: np.ndarray,
    reach_radii: np.ndarray,
    *,
    sigma_smooth: float,
) -> IpoptOutcome:
    """Solve for the selected obstacles (arrays of length <= ``program.n_slots``).

    Args:
        program: Built solver.
        prior: GP prior (for the sizes).
        z0: Initial guess of the trajectory variables.
        goal: Start-relative target.
        centres: Start-relative obstacle centres.
        required: Distance every waypoint (segment) must keep from each obstacle, margins
            included.
        reach_radii: Per-waypoint reach bound (N,); pairs that cannot come closer than the
            required distance get infinite bounds.
        sigma_smooth: Smoothness budget.
    """
    n = prior.n_waypoints - 1
    m = len(centres)
    slots = program.n_slots
    centres_p = np.zeros((slots, 2))
    centres_p[:m] = centres
    params = np.concatenate([goal, centres_p.ravel()])
    need = np.zeros(slots)
    need[:m] = np.maximum(required, 0.0)
    distance = length(*point_offset(0.0, 0.0, centres_p[:, 0], centres_p[:, 1]))  # from x_1
    active = np.zeros(slots, dtype=bool)
    active[:m] = required > 0.0  # a row ||x - o||^2 >= 0 is vacuous (and degenerate at x = o)
    lbg = [np.array([-np.inf])]
    ubg = [np.array([sigma_smooth])]
    x0 = np.zeros(program.n_var)
    x0[: prior.n_var] = z0
    lbx = np.full(program.n_var, -np.inf)
    ubx = np.full(program.n_var, np.inf)
    if not program.continuous:
        # rows ordered obstacle-major: for j, for i in 2..N
        reachable = (distance[:, None] - reach_radii[None, 1:]) < need[:, None] + 1e-9
        on = active[:, None] & reachable
        lbg.append(np.where(on, need[:, None] ** 2, -np.inf).ravel())
        ubg.append(np.full(slots * n, np.inf))
    else:
        positions = np.zeros((n + 1, 2))
        positions[1:] = z0[: 2 * n].reshape(n, 2)
        seg_reach = np.maximum(reach_radii[:-1], reach_radii[1:])
        seg_reach[0] = reach_radii[1]
        on = active[:, None] & ((distance[:, None] - seg_reach[None, :]) < need[:, None] + 1e-9)
        rows_l = np.empty((slots, n, 3))
        rows_u = np.empty((slots, n, 3))
        rows_l[..., 0] = rows_l[..., 1] = np.where(on, need[:, None], -np.inf)
        rows_l[..., 2] = -np.inf
        rows_u[..., 0] = rows_u[..., 1] = np.inf
        rows_u[..., 2] = np.where(on, 1.0, np.inf)
        lbg.append(rows_l.ravel())
        ubg.append(rows_u.ravel())
        # initial separating directions: from the centre to the segment's closest point
        normals = np.zeros((slots, n, 2))
        if m:
            dx, dy = segment_offsets(positions, centres, eps=1e-12)
            d = np.stack((dx.T, dy.T), axis=-1)
            # the direction of the offset, normalised by np.hypot as these initial guesses were
            # recorded (length() moves IPOPT's continuous plans by up to 2e-10 m)
            norm = np.hypot(dx, dy).T[..., None]
            normals[:m] = np.where(norm > 1e-9, d / np.maximum(norm, 1e-9), 0.0)
        x0[prior.n_var :] = normals.ravel()
        fixed = np.repeat(~on.ravel(), 2)
        lbx[prior.n_var :][fixed] = 0.0
        ubx[prior.n_var :][fixed] = 0.0
        x0[prior.n_var :][fixed] = 0.0
    solution = program.solver(
        x0=x0, p=params, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg), lbx=lbx, ubx=ubx
    )
    stats = program.solver.stats()
    z = np.asarray(solution["x"]).ravel()[: prior.n_var]
    return IpoptOutcome(
        z, str(stats.get("return_status", "unknown")), bool(stats.get("success", False)),
        int(stats.get("iter_count", -1)),
    )


#: The two attempts and their compiled programs (they differ in the iteration cap).
ATTEMPTS: tuple[str, ...] = ("first", "cold")

_STATUS = {
    "Solve_Succeeded": "solved",
    "Solved_To_Acceptable_Level": "solved_acceptable",
    "Maximum_Iterations_Exceeded": "max_iter",
    "Maximum_WallTime_Exceeded": "max_wall_time",
}


def ipopt_status(status: str) -> str:
    """IPOPT's return status as the planner reports it (``solved``, ``max_iter`` ...)."""
    return _STATUS.get(status, status)


class IpoptBackend:
    """Solve the prepared problem with IPOPT (see the module docstring).

    Attributes:
        context: The problem's settings, prior and certificate.
        settings: The IPOPT knobs.
        options: IPOPT options: :data:`IPOPT_OPTIONS` with ``settings.options`` over.
        selection_reach: Obstacles beyond this (m) are not given to IPOPT.
        programs: Compiled programs by (obstacle-slot count, attempt); not pickled.
    """

    def __init__(self, context: ProblemContext, settings: IpoptSettings) -> None:
        self.context = context
        self.settings = settings
        self.options: dict[str, object] = dict(IPOPT_OPTIONS, **settings.options)
        self.selection_reach = hard_constraint_reach(context)
        self.programs: dict[tuple[int, str], IpoptProgram] = {}

    def program(self, n_slots: int, attempt: str) -> IpoptProgram:
        """The compiled program for ``n_slots`` obstacle slots and ``attempt`` (built once)."""
        key = (n_slots, attempt)
        if key not in self.programs:
            s = self.context.settings
            options = dict(self.options)
            options["max_iter"] = (self.settings.first_max_iter if attempt == "first"
                                   else self.settings.max_iter)
            self.programs[key] = build_ipopt(
                self.context.prior,
                n_slots,
                smooth_regulariser=s.smooth_weight,
                continuous=s.continuous,
                ipopt_options=options,
            )
        return self.programs[key]

    def warmup(self, slot_counts: Iterable[int], attempts: Iterable[str] = ATTEMPTS) -> None:
        """Build the programs of ``attempts`` for these slot counts now."""
        kinds = tuple(attempts)
        for slots in slot_counts:
            for attempt in kinds:
                self.program(slots, attempt)

    def solve(self, prepared: PreparedProblem, warm: np.ndarray | None = None) -> Iterate:
        """Plan with IPOPT: the first attempt if it passes the certificate, else the cold one."""
        context = self.context
        s = context.settings
        prep = prepared
        sel = prep.selected
        n_slots = bucket_size(len(sel), s.max_obstacles)
        args = (context.target(prep), prep.centres[sel], context.solver_need(prep),
                context.reach_radii)
        kwargs = {"sigma_smooth": s.sigma_smooth}
        iterations = 0
        if self.settings.first_max_iter > 0 and not prep.escape_mode:
            z0 = warm if warm is not None else context.guess(prep)
            first = solve_ipopt(self.program(n_slots, "first"), context.prior, z0, *args,
                                **kwargs)
            iterations += max(first.iterations, 0)
            if first.success and context.certificate.passes(prep, first.z):
                return Iterate(first.z, ipopt_status(first.status), iterations)
        # cold attempt from the stationary trajectory, which is feasible
        second = solve_ipopt(self.program(n_slots, "cold"), context.prior,
                             np.zeros(context.prior.n_var), *args, **kwargs)
        iterations += max(second.iterations, 0)
        return Iterate(second.z, ipopt_status(second.status), iterations)

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the compiled programs (CasADi objects); they are rebuilt lazily."""
        return {**self.__dict__, "programs": {}}
