"""``SafeTrajectoryPlanner``: the safe trajectory optimiser of thesis §3.5.2 behind one interface.

Three backends solve the same problem (Eqs. 3.3-3.7, SPEC §2.2): ``ipopt`` (hard pairwise
constraints), ``lm`` (the thesis' penalty form, Eq. 3.8, with Levenberg-Marquardt; fixed or
adaptive lambda, App. B.2.3) and ``scp`` (convex QPs on OSQP with tangent half-spaces). Every
result, whatever the backend, is checked against every obstacle given; a plan that fails the check
is replaced by the stationary trajectory (thesis §3.5.2: the stationary trajectory is feasible
whenever the start is) and flagged as a fallback.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from solvers.planner.batch import (
    default_workers,
    failure_error,
    get_pool,
    is_failure,
    planner_blob,
)
from solvers.planner.geometry import point_distances, segment_distances
from solvers.planner.ipopt import IPOPT_OPTIONS, IpoptProgram, build_ipopt, solve_ipopt
from solvers.planner.lm import LMKernel, LMWeights, build_lm_functions, levenberg_marquardt
from solvers.planner.problem import (
    BACKENDS,
    ESCAPE_TOLERANCE,
    PreparedProblem,
    bucket_size,
    build_gp_prior,
    detour_guess,
    join,
    prepare,
    split,
)
from solvers.planner.result import PlanResult
from solvers.planner.scp import ScpProgram

logger = logging.getLogger(__name__)

#: Tolerance of the certificate (metres): a plan passes when every distance >= required - this.
CERTIFICATE_TOLERANCE = 1e-9
#: Work of a problem for the batch timing, in solver iterations: its iterations plus this (the
#: preparation, initial guesses and certificate cost about two iterations).
BATCH_WORK_PER_PROBLEM = 2
#: Budget weight (relative to lambda) used only to rank LM's initial guesses.
CANDIDATE_BUDGET_FACTOR = 0.01


@dataclass
class _BackendPlan:
    z: np.ndarray
    status: str
    iterations: int
    multiplier: float = float("nan")
    failed: bool = False
    rescued: bool = False


class SafeTrajectoryPlanner:
    """Plan N waypoints from a start towards a subgoal that keep eps' from every obstacle.

    Args:
        backend: ``"ipopt"``, ``"lm"`` or ``"scp"``.
        n_waypoints: N, waypoints including the start (thesis: 30).
        clearance: eps' (thesis: 0.5 m); an obstacle with radius r needs eps' + r.
        max_obstacles: Most obstacles given to a backend (the nearest reachable ones are kept;
            the certificate checks all).
        dt: Time between waypoints of the GP prior (s); with ``Q_c = I`` only ``sigma_smooth dt^-3``
            matters (the public code's horizon of 10 s over 29 intervals by default).
        sigma_smooth: Smoothness budget ``h_smooth <= sigma_smooth`` (Eq. 3.3). The farthest
            any waypoint can get is ``sqrt(sigma_smooth T^3 / 3)``, T = (N - 1) dt: 4 m by default.
        smooth_weight: rho, a small weight on ``h_smooth`` added to the objective of every
            backend: among plans that get equally close to the subgoal it picks the smoothest, and
            it makes the problem strictly convex away from obstacles.
        continuous: Also keep the clearance along every segment between waypoints.
        goal_tolerance: ``reached_subgoal`` is ``||x_N - subgoal|| < goal_tolerance`` (m).
        feasibility_margin: Extra clearance (m) asked of IPOPT and SCP, which solve to a
            tolerance; the certificate checks the exact clearance.
        lm_iterations: LM iterations per lambda (thesis: 10 in training).
        lm_lambda: The multiplier lambda of Eq. 3.8 (fixed mode; the start of adaptive mode).
        lm_adaptive: Double lambda until the plan passes the certificate, up to ``lm_lambda_max``
            (App. B.2.3; the evaluation setting).
        lm_lambda_max: Largest lambda, also used in escape mode (thesis: 1024).
        lm_obstacle_weight: Base weight of the obstacle hinge (times lambda).
        lm_budget_weight: Base weight of the smoothness-budget hinge (times lambda).
        lm_margin: Extra clearance (m) in the LM hinge, so penalty solutions usually pass the
            exact certificate (the public code adds 0.01 m).
        lm_damping: Initial Marquardt damping.
        ipopt_max_iter: IPOPT iteration cap of the cold (stationary-start) attempt.
        ipopt_first_max_iter: Iteration cap of the first attempt from the guess / previous plan.
        ipopt_options: IPOPT options merged over :data:`IPOPT_OPTIONS`.
        scp_max_iterations: QP solves at most.
        scp_trust_region: Half-width of the SCP trust-region box.
        rescue_backend: ``None`` (default) or ``"ipopt"``: when the LM or SCP plan fails the
            certificate, solve the same problem with IPOPT (cold, hard constraints) before
            falling back to the stationary plan. Costs IPOPT's time only on those rare problems
            (LM's escape-mode starts between two close obstacles are the usual case; see
            solvers/README.md "Rescue"). Ignored with ``backend="ipopt"``.
    """

    def __init__(
        self,
        backend: str = "ipopt",
        n_waypoints: int = 30,
        clearance: float = 0.5,
        max_obstacles: int = 16,
        dt: float = 10.0 / 29.0,
        sigma_smooth: float = 0.048,
        smooth_weight: float = 0.01,
        continuous: bool = False,
        goal_tolerance: float = 0.05,
        feasibility_margin: float = 1e-5,
        lm_iterations: int = 10,
        lm_lambda: float = 1.0,
        lm_adaptive: bool = False,
        lm_lambda_max: float = 1024.0,
        lm_obstacle_weight: float = 1000.0,
        lm_budget_weight: float = 100.0,
        lm_margin: float = 0.02,
        lm_damping: float = 1e-4,
        ipopt_max_iter: int = 200,
        ipopt_first_max_iter: int = 30,
        ipopt_options: dict[str, object] | None = None,
        scp_max_iterations: int = 30,
        scp_trust_region: float = 1.0,
        rescue_backend: str | None = None,
    ) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
        if rescue_backend not in (None, "ipopt"):
            raise ValueError(f"rescue_backend must be None or 'ipopt', got {rescue_backend!r}")
        positive = {
            "dt": dt,
            "sigma_smooth": sigma_smooth,
            "lm_lambda": lm_lambda,
            "lm_lambda_max": lm_lambda_max,
            "lm_obstacle_weight": lm_obstacle_weight,
            "lm_budget_weight": lm_budget_weight,
            "lm_damping": lm_damping,
            "scp_trust_region": scp_trust_region,
            "goal_tolerance": goal_tolerance,
        }
        for name, value in positive.items():
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        non_negative = {
            "clearance": clearance,
            "smooth_weight": smooth_weight,
            "feasibility_margin": feasibility_margin,
            "lm_margin": lm_margin,
        }
        for name, value in non_negative.items():
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        counts = {
            "n_waypoints": (n_waypoints, 3),
            "max_obstacles": (max_obstacles, 1),
            "lm_iterations": (lm_iterations, 1),
            "ipopt_max_iter": (ipopt_max_iter, 1),
            "ipopt_first_max_iter": (ipopt_first_max_iter, 0),
            "scp_max_iterations": (scp_max_iterations, 1),
        }
        for name, (value, least) in counts.items():
            if int(value) != value or value < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
        if lm_lambda > lm_lambda_max:
            raise ValueError(f"lm_lambda ({lm_lambda}) must be <= lm_lambda_max ({lm_lambda_max})")
        self.backend = backend
        self.n_waypoints = int(n_waypoints)
        self.clearance = float(clearance)
        self.max_obstacles = int(max_obstacles)
        self.dt = float(dt)
        self.sigma_smooth = float(sigma_smooth)
        self.smooth_weight = float(smooth_weight)
        self.continuous = bool(continuous)
        self.goal_tolerance = float(goal_tolerance)
        self.feasibility_margin = float(feasibility_margin)
        self.lm_iterations = int(lm_iterations)
        self.lm_lambda = float(lm_lambda)
        self.lm_adaptive = bool(lm_adaptive)
        self.lm_lambda_max = float(lm_lambda_max)
        self.lm_margin = float(lm_margin)
        self.lm_damping = float(lm_damping)
        self.ipopt_max_iter = int(ipopt_max_iter)
        self.ipopt_first_max_iter = int(ipopt_first_max_iter)
        self.ipopt_options = dict(IPOPT_OPTIONS, **(ipopt_options or {}))
        self.scp_max_iterations = int(scp_max_iterations)
        self.scp_trust_region = float(scp_trust_region)
        #: None with backend="ipopt" (nothing to rescue with)
        self.rescue_backend = rescue_backend if backend != "ipopt" else None
        self.prior = build_gp_prior(self.n_waypoints, self.dt)
        self.reach_radii = self.prior.reach_radii(self.sigma_smooth)
        #: Farthest any waypoint of an admissible plan can get from the start (m).
        self.reach = float(self.reach_radii[-1])
        self._lm_weights = LMWeights(
            smooth_regulariser=self.smooth_weight,
            smooth_budget=float(lm_budget_weight),
            obstacle=float(lm_obstacle_weight),
            sigma_smooth=self.sigma_smooth,
        )
        self._lm_kernels: dict[int, LMKernel] = {}
        self._ipopt: dict[tuple[int, str], IpoptProgram] = {}
        self._scp: dict[int, ScpProgram] = {}
        self._previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._batch_cache: tuple[object, bytes, bytes] | None = None

    # ------------------------------------------------------------------ public API
    def plan(
        self,
        start: Sequence[float] | np.ndarray,
        subgoal: Sequence[float] | np.ndarray,
        obstacles: Sequence[Sequence[float]] | np.ndarray | None = None,
        warm_start: bool = True,
    ) -> PlanResult:
        """Plan from ``start`` towards ``subgoal`` around ``obstacles``.

        Args:
            start: Robot root position (2,).
            subgoal: Target of the last waypoint (2,).
            obstacles: (m, 2) centres or (m, 3) centres with radii; None or empty for none.
            warm_start: When the subgoal moved less than 0.25 m since the previous call, use the
                rest of the previous plan (from its waypoint nearest to the new start on) as an
                initial guess (receding-horizon use).

        Returns:
            The certified plan (see :class:`PlanResult`).

        Raises:
            ValueError: Non-finite or wrongly shaped inputs, or negative radii.
        """
        tic = time.perf_counter()
        prep = self._prepare(start, subgoal, obstacles)
        warm = self._warm_guess(prep) if warm_start else None
        try:
            if self.backend == "lm":
                plan = self._solve_lm(prep, warm)
            elif self.backend == "ipopt":
                plan = self._solve_ipopt(prep, warm)
            else:
                plan = self._solve_scp(prep, warm)
        except Exception as error:  # a solver crash must not end a training run: fall back
            logger.warning("planner backend %s failed: %r", self.backend, error)
            plan = _BackendPlan(np.zeros(self.prior.n_var), f"error: {error}", 0, failed=True)
        if self.rescue_backend is not None and (plan.failed or not self._passes(prep, plan.z)):
            plan = self._rescue(prep, plan)
        result = self._certify(prep, plan, tic)
        self._previous = (prep.start.copy(), prep.start + prep.goal, result.waypoints.copy())
        return result

    def plan_batch(
        self,
        starts: Sequence[Sequence[float]] | np.ndarray,
        subgoals: Sequence[Sequence[float]] | np.ndarray,
        obstacles_list: Sequence[object],
        workers: int | None = None,
    ) -> list[PlanResult]:
        """Plan several independent problems (e.g. one per vectorised environment).

        Every problem is solved as ``plan(start, subgoal, obstacles, warm_start=False)`` solves
        it, certificate and fallback included, so the plans equal those of a loop of ``plan``
        calls: exactly for IPOPT and LM, to about 1e-8 m for SCP (OSQP carries rounding state
        from one QP to the next, so SCP plans depend slightly on the problems solved before, in a
        loop too). Afterwards the warm-start memory holds the last problem, as after the loop.

        Speed comes from a second core: the problems are shared with ``workers - 1`` helper
        processes (:mod:`solvers.planner.batch`), which claim them one at a time. Threads cannot
        do this: CasADi keeps the GIL while IPOPT or an LM kernel runs (a thread pool measured
        0.9-1.0x the loop). The helpers start on the first call that wants them and build each
        planner configuration once; until they are ready the batch runs here alone, so call
        :meth:`start_batch_workers` to start them ahead. The gain needs an idle core: when every
        core is busy with other jobs sharing can be slower than the loop (solvers/README.md),
        hence the measured default below. A
        lockstep LM variant (one mapped CasADi call and one block-diagonal banded solve per
        iteration for all problems) was measured no faster than the loop and was dropped.

        Args:
            starts: (B, 2) start positions.
            subgoals: (B, 2) subgoals.
            obstacles_list: B obstacle arrays ((m, 2) or (m, 3); None or empty for none).
            workers: Processes solving, this one included. None (default): up to
                ``min(2, usable CPUs)``, sharing or not by measurement, per planner
                configuration and batch size: both ways are tried, then the one with the lower
                running mean of wall time per unit of work (solver iterations) is used, and
                every 8th batch tries the other again. An explicit ``workers > 1`` always
                shares; 1 solves the problems one after the other here.

        Returns:
            One certified :class:`PlanResult` per problem, in order.

        Raises:
            ValueError: Mismatched shapes, ``workers < 1``, or a problem ``plan`` rejects (the
                first such problem's error).
        """
        starts_arr = np.asarray(starts, dtype=float)
        subgoals_arr = np.asarray(subgoals, dtype=float)
        if starts_arr.ndim != 2 or starts_arr.shape[1] != 2:
            raise ValueError(f"starts must have shape (B, 2), got {starts_arr.shape}")
        if subgoals_arr.shape != starts_arr.shape:
            raise ValueError(
                f"subgoals must have the same shape as starts {starts_arr.shape}, "
                f"got {subgoals_arr.shape}"
            )
        if len(obstacles_list) != len(starts_arr):
            raise ValueError(
                f"obstacles_list must have one entry per start ({len(starts_arr)}), "
                f"got {len(obstacles_list)}"
            )
        count = default_workers() if workers is None else workers
        if int(count) != count or count < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        tasks = list(zip(starts_arr, subgoals_arr, obstacles_list, strict=True))
        share = count > 1 and len(tasks) > 1
        key = None
        if share and workers is None:  # measured choice (see HelperPool.choose_shared)
            key = (self._batch_config()[1], len(tasks))
            share = get_pool().choose_shared(key)
        tic = time.perf_counter()
        shared = self._plan_shared(tasks, int(count)) if share else None
        if shared is None:
            results = [self.plan_task(task) for task in tasks]
        else:
            for value in shared:
                if is_failure(value):
                    raise failure_error(value)
            start, subgoal = starts_arr[-1], subgoals_arr[-1]
            self._previous = (start.copy(), start + (subgoal - start),
                              shared[-1].waypoints.copy())
            results = shared
        if key is not None:
            work = sum(r.iterations + BATCH_WORK_PER_PROBLEM for r in results)
            get_pool().record(key, shared is not None, time.perf_counter() - tic, work)
        return results

    def plan_task(self, task: tuple[object, object, object]) -> PlanResult:
        """``plan(start, subgoal, obstacles, warm_start=False)`` for a (start, subgoal,
        obstacles) tuple: one problem of a batch."""
        start, subgoal, obstacles = task
        return self.plan(start, subgoal, obstacles, warm_start=False)

    def start_batch_workers(self, workers: int | None = None, timeout: float = 60.0) -> int:
        """Start the helper processes of :meth:`plan_batch` now and wait until they are ready.

        Args:
            workers: As in :meth:`plan_batch` (helpers: ``workers - 1``).
            timeout: Seconds to wait at most.

        Returns:
            The number of helpers ready to solve this planner's problems.
        """
        count = default_workers() if workers is None else int(workers)
        if count <= 1:
            return 0
        pool = get_pool()
        blob, digest = self._batch_config()
        with pool.lock:
            return pool.wait_ready(count - 1, digest, blob, timeout)

    def _batch_config(self) -> tuple[bytes, bytes]:
        """The pickled configuration sent to the helpers and its digest, cached while the
        settings (every scalar attribute, the LM weights and the IPOPT options) stay the same."""
        fingerprint = (
            tuple((k, v) for k, v in sorted(self.__dict__.items())
                  if isinstance(v, bool | int | float | str) and not k.startswith("_batch")),
            self._lm_weights,
            tuple(sorted((k, repr(v)) for k, v in self.ipopt_options.items())),
        )
        cached = self._batch_cache
        if cached is None or cached[0] != fingerprint:
            state = self.__getstate__()
            state["_previous"] = None
            cached = (fingerprint, *planner_blob(state))
            self._batch_cache = cached
        return cached[1], cached[2]

    def _plan_shared(self, tasks: list[tuple[object, object, object]], count: int) -> list | None:
        """Solve ``tasks`` here and in the helper processes; None when no helper is ready."""
        try:
            pool = get_pool()
        except OSError as error:  # no shared memory: solve here
            logger.warning("planner batch helpers unavailable: %r", error)
            return None
        if not pool.lock.acquire(blocking=False):  # another thread is using the helpers
            return None
        try:
            blob, digest = self._batch_config()
            helpers = pool.prepare(count - 1, digest, blob)
            if not helpers:
                return None
            # plain lists pickle several times faster than small arrays; same values
            wire = [(s.tolist(), g.tolist(), o.tolist() if isinstance(o, np.ndarray) else o)
                    for s, g, o in tasks]
            return pool.run(self.plan_task, tasks, wire, helpers, digest)
        finally:
            pool.lock.release()

    def __getstate__(self) -> dict[str, object]:
        """Pickle without the compiled solvers (CasADi/OSQP objects); they are rebuilt lazily.

        So a planner can be sent to vectorised-environment worker processes.
        """
        state = dict(self.__dict__)
        state["_lm_kernels"] = {}
        state["_ipopt"] = {}
        state["_scp"] = {}
        state["_batch_cache"] = None  # digest of the configuration sent to batch helpers
        return state

    def warmup(self) -> SafeTrajectoryPlanner:
        """Build every compiled solver now (one per obstacle-slot count) instead of on first use,
        the rescue's IPOPT programs included."""
        counts = sorted({bucket_size(k, self.max_obstacles) for k in range(self.max_obstacles + 1)})
        for count in counts:
            if self.backend == "lm":
                self._lm_kernel(count)
            elif self.backend == "ipopt":
                self._ipopt_program(count, "first")
            else:
                self._scp_program(count)
            if self.backend == "ipopt" or self.rescue_backend == "ipopt":
                self._ipopt_program(count, "cold")  # the rescue's (cold) program
        return self

    # ------------------------------------------------------------------ preparation
    def _prepare(self, start: object, subgoal: object, obstacles: object) -> PreparedProblem:
        reach = self.reach
        if self.backend == "lm":
            # The penalty budget is soft: allow the plan to overrun it (the bound is used only
            # to drop far obstacles; the certificate still checks all of them).
            reach = float(np.sqrt(4.0 * self.sigma_smooth / self.prior.reach_coef[-1]))
        return prepare(
            start,
            subgoal,
            obstacles,
            clearance=self.clearance,
            reach=reach + self.feasibility_margin + self.lm_margin,
            max_obstacles=self.max_obstacles,
        )

    def _warm_guess(self, prep: PreparedProblem) -> np.ndarray | None:
        if self._previous is None:
            return None
        _, previous_goal, waypoints = self._previous
        if np.hypot(*(prep.start + prep.goal - previous_goal)) > 0.25:
            return None
        rest = waypoints - prep.start
        nearest = int(np.argmin(np.einsum("nk,nk->n", rest, rest)))
        positions = np.zeros_like(rest)
        tail = rest[nearest + 1 :]
        positions[1 : 1 + len(tail)] = tail
        positions[1 + len(tail) :] = rest[-1]
        velocities = np.zeros_like(positions)
        velocities[1:] = np.diff(positions, axis=0) / self.dt
        return join(positions, velocities)

    def _solver_need(self, prep: PreparedProblem) -> np.ndarray:
        """Distances asked of IPOPT / SCP for the selected obstacles: the clearance plus the
        feasibility margin, or in escape mode the start's distance less a tenth of the escape
        tolerance (the certificate allows the full tolerance)."""
        sel = prep.selected
        return np.where(
            prep.escape[sel],
            prep.start_distances[sel] - 0.1 * ESCAPE_TOLERANCE,
            prep.required[sel] + self.feasibility_margin,
        )

    def _target(self, prep: PreparedProblem) -> np.ndarray:
        """The start-relative point the plan aims at: the subgoal, or the escape target."""
        return self._escape_target(prep) if prep.escape_mode else prep.goal

    def _guess(self, prep: PreparedProblem) -> np.ndarray:
        sel = prep.selected
        return detour_guess(
            self.prior, self._target(prep), prep.centres[sel], prep.clearances[sel],
            reach=self.reach,
        )

    # ------------------------------------------------------------------ LM
    def _lm_kernel(self, n_slots: int) -> LMKernel:
        if n_slots not in self._lm_kernels:
            step, cost = build_lm_functions(
                self.prior, self._lm_weights, n_slots, continuous=self.continuous
            )
            self._lm_kernels[n_slots] = LMKernel(step, cost, self.n_waypoints)
        return self._lm_kernels[n_slots]

    def _lm_params(
        self, prep: PreparedProblem, n_slots: int, lam: float, budget_factor: float = 1.0
    ) -> np.ndarray:
        sel = prep.selected
        m = len(sel)
        centres = np.zeros((n_slots, 2))
        centres[:m] = prep.centres[sel]
        radii = np.zeros(n_slots)
        # escape obstacles: "no closer than the start", without margin (the first waypoints
        # cannot get farther than the start at once; the target pulls away from them anyway)
        radii[:m] = np.where(
            prep.escape[sel],
            prep.start_distances[sel] - 0.1 * ESCAPE_TOLERANCE,
            prep.required[sel] + self.lm_margin,
        )
        # escape mode: the target is outside the violated clearances and weighs as much as the
        # constraints (lambda_max), so the plan actually leaves
        goal_scale = np.sqrt(lam) if prep.escape_mode else 1.0
        return np.concatenate(
            [self._target(prep), centres.ravel(), radii, [lam, lam * budget_factor, goal_scale]]
        )

    def _solve_lm(self, prep: PreparedProblem, warm: np.ndarray | None) -> _BackendPlan:
        n_slots = bucket_size(len(prep.selected), self.max_obstacles)
        kernel = self._lm_kernel(n_slots)
        lam = self.lm_lambda_max if prep.escape_mode else self.lm_lambda
        # rank the initial guesses by goal distance and clearance, barely by the budget: LM
        # repairs a budget overrun quickly, while a stationary start cannot pick a side around
        # an obstacle that sits exactly on the straight line
        kernel.p[:] = self._lm_params(prep, n_slots, lam, CANDIDATE_BUDGET_FACTOR)
        z = min(self._lm_candidates(prep, warm), key=kernel.cost_at)
        total = 0
        while True:
            kernel.p[:] = self._lm_params(prep, n_slots, lam)
            z, _, done = levenberg_marquardt(
                kernel, z, iterations=self.lm_iterations, damping=self.lm_damping
            )
            total += done
            if not self.lm_adaptive or lam >= self.lm_lambda_max or self._passes(prep, z):
                break
            lam = min(2.0 * lam, self.lm_lambda_max)
        return self._lm_repair(prep, _BackendPlan(z, "solved", total, lam))

    def _lm_repair(self, prep: PreparedProblem, plan: _BackendPlan) -> _BackendPlan:
        """Shrink a penalty plan that fails the certificate towards the start.

        ``theta z`` (every waypoint moved towards the start by the factor theta, velocities
        likewise) is exactly as smooth up to ``theta^2``; the largest theta in 0.9, 0.8, ... 0.1
        that passes the certificate is kept (status ``solved_shortened``) before falling back to
        the stationary trajectory.
        """
        if self._passes(prep, plan.z):
            return plan
        for theta in np.arange(0.9, 0.05, -0.1):
            if self._passes(prep, theta * plan.z):
                return _BackendPlan(theta * plan.z, f"solved_shortened(theta={theta:.1f})",
                                    plan.iterations, plan.multiplier)
        return plan

    def _lm_candidates(self, prep: PreparedProblem, warm: np.ndarray | None) -> list[np.ndarray]:
        """Initial guesses for LM; the one with the lowest penalty cost is used.

        The detour guess, the straight smoothest path to the (reach-clipped) goal, each scaled
        towards the start to fit the smoothness budget, and the stationary trajectory (the
        thesis' initialisation, hinge-free whenever the start is clear).
        """
        goal = self._target(prep)
        distance = float(np.hypot(*goal))
        target = goal if distance <= self.reach else goal * (self.reach / distance)
        candidates = [np.zeros(self.prior.n_var), self.prior.goal_map @ target]
        if len(prep.selected):
            detour = self._guess(prep)
            candidates.append(detour)
            h = self.prior.smoothness(detour)
            if h > self.sigma_smooth:
                candidates.append(detour * np.sqrt(self.sigma_smooth / h))
        if warm is not None:
            candidates.append(warm)
        return candidates

    # ------------------------------------------------------------------ IPOPT
    def _ipopt_program(self, n_slots: int, kind: str) -> IpoptProgram:
        key = (n_slots, kind)
        if key not in self._ipopt:
            options = dict(self.ipopt_options)
            first = kind == "first"
            options["max_iter"] = self.ipopt_first_max_iter if first else self.ipopt_max_iter
            self._ipopt[key] = build_ipopt(
                self.prior,
                n_slots,
                smooth_regulariser=self.smooth_weight,
                continuous=self.continuous,
                ipopt_options=options,
            )
        return self._ipopt[key]

    def _solve_ipopt(self, prep: PreparedProblem, warm: np.ndarray | None) -> _BackendPlan:
        sel = prep.selected
        n_slots = bucket_size(len(sel), self.max_obstacles)
        args = (self._target(prep), prep.centres[sel], self._solver_need(prep), self.reach_radii)
        kwargs = {"sigma_smooth": self.sigma_smooth}
        iterations = 0
        if self.ipopt_first_max_iter > 0 and not prep.escape_mode:
            z0 = warm if warm is not None else self._guess(prep)
            first = solve_ipopt(self._ipopt_program(n_slots, "first"), self.prior, z0, *args,
                                **kwargs)
            iterations += max(first.iterations, 0)
            if first.success and self._passes(prep, first.z):
                return _BackendPlan(first.z, _ipopt_status(first.status), iterations)
        # cold attempt from the stationary trajectory, which is feasible
        second = solve_ipopt(self._ipopt_program(n_slots, "cold"), self.prior,
                             np.zeros(self.prior.n_var), *args, **kwargs)
        iterations += max(second.iterations, 0)
        return _BackendPlan(second.z, _ipopt_status(second.status), iterations)

    def _rescue(self, prep: PreparedProblem, failed: _BackendPlan) -> _BackendPlan:
        """IPOPT's plan for a problem whose LM / SCP plan failed the certificate, or the
        failed plan when IPOPT fails too (then :meth:`_certify` falls back)."""
        try:
            rescue = self._solve_ipopt(prep, None)
        except Exception as error:  # as in plan: a solver crash must not end a run
            logger.warning("planner rescue by ipopt failed: %r", error)
            return failed
        iterations = failed.iterations + rescue.iterations
        if not self._passes(prep, rescue.z):
            return _BackendPlan(failed.z, f"{failed.status}; ipopt rescue: {rescue.status}",
                                iterations, failed.multiplier, failed.failed)
        return _BackendPlan(rescue.z, f"rescued by ipopt ({failed.status}): {rescue.status}",
                            iterations, rescued=True)

    # ------------------------------------------------------------------ SCP
    def _scp_program(self, n_slots: int) -> ScpProgram:
        if n_slots not in self._scp:
            self._scp[n_slots] = ScpProgram(
                self.prior, n_slots, smooth_regulariser=self.smooth_weight,
                continuous=self.continuous,
            )
        return self._scp[n_slots]

    def _solve_scp(self, prep: PreparedProblem, warm: np.ndarray | None) -> _BackendPlan:
        sel = prep.selected
        need = self._solver_need(prep)
        exact_need = np.where(
            prep.escape[sel], need, prep.required[sel] + 0.5 * self.feasibility_margin
        )
        z0 = np.zeros(self.prior.n_var)
        guess = self._guess(prep)
        candidates = [c for c in (warm, guess) if c is not None]
        for candidate in candidates:
            h = self.prior.smoothness(candidate)
            if h > self.sigma_smooth:
                candidate = candidate * np.sqrt(self.sigma_smooth / h) * (1.0 - 1e-9)
            if self._clear_of(prep, candidate, sel, need):
                z0 = candidate
                break
        program = self._scp_program(bucket_size(len(sel), self.max_obstacles))
        outcome = program.solve(
            z0,
            self._target(prep),
            prep.centres[sel],
            need,
            sigma_smooth=self.sigma_smooth,
            trust_region=self.scp_trust_region,
            max_iterations=self.scp_max_iterations,
            exact_need=exact_need,
        )
        return _BackendPlan(outcome.z, outcome.status, outcome.iterations)

    def _escape_target(self, prep: PreparedProblem) -> np.ndarray:
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

    # ------------------------------------------------------------------ certificate
    def _clear_of(
        self, prep: PreparedProblem, z: np.ndarray, sel: np.ndarray, need: np.ndarray
    ) -> bool:
        if len(sel) == 0:
            return True
        positions, _ = split(z, self.n_waypoints)
        centres = prep.centres[sel]
        distances = (segment_distances(positions, centres) if self.continuous
                     else point_distances(positions[1:], centres))
        return bool(np.all(distances >= need[None, :]))

    def _passes(self, prep: PreparedProblem, z: np.ndarray) -> bool:
        """Certificate: each waypoint (segment) keeps its required distance to every obstacle."""
        if not np.all(np.isfinite(z)):
            return False
        if len(prep.centres) == 0:
            return True
        positions, _ = split(z, self.n_waypoints)
        distances = (segment_distances(positions, prep.centres) if self.continuous
                     else point_distances(positions, prep.centres))
        return bool(np.all(distances >= prep.required[None, :] - CERTIFICATE_TOLERANCE))

    def _certify(self, prep: PreparedProblem, plan: _BackendPlan, tic: float) -> PlanResult:
        """Check the plan against every obstacle; replace it by the stationary one if it fails."""
        z = plan.z
        status = plan.status
        fallback = plan.failed or not np.all(np.isfinite(z))
        if fallback:
            z = np.zeros(self.prior.n_var)
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
            if not fallback and not np.all(checked >= prep.required[None, :] - floor):
                fallback = True
                status = f"fallback: {plan.status}: plan failed the clearance certificate"
                positions[:] = 0.0
                velocities[:] = 0.0
                point = np.broadcast_to(prep.start_distances, point.shape)
                segment = np.broadcast_to(prep.start_distances, segment.shape)
                checked = segment if self.continuous else point
            min_clear = float(np.min(point - radii[None, :]))
            min_cont = float(np.min(segment - radii[None, :]))
            feasible = bool(np.all(checked >= prep.clearances[None, :] - floor))
        gap = positions[-1] - prep.goal
        objective = float(gap @ gap)
        return PlanResult(
            waypoints=positions + prep.start,
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
            backend=self.backend,
            reached_subgoal=bool(np.sqrt(objective) < self.goal_tolerance),
            multiplier=float(plan.multiplier),
            n_considered=len(prep.selected),
            rescued=plan.rescued and not fallback,
        )


def _ipopt_status(status: str) -> str:
    return {
        "Solve_Succeeded": "solved",
        "Solved_To_Acceptable_Level": "solved_acceptable",
        "Maximum_Iterations_Exceeded": "max_iter",
        "Maximum_WallTime_Exceeded": "max_wall_time",
    }.get(status, status)
