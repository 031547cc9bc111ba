"""``SafeTrajectoryPlanner``: the safe trajectory optimiser of thesis §3.5.2 behind one interface.

Three backends solve the same problem (Eqs. 3.3-3.7): ``ipopt`` (hard pairwise constraints),
``lm`` (the thesis' penalty form, Eq. 3.8, with Levenberg-Marquardt; fixed or adaptive lambda,
App. B.2.3) and ``scp`` (convex QPs on OSQP with tangent half-spaces). A plan goes through four
steps, each in its own module: validate and select the obstacles (:mod:`.context`), solve
(:mod:`.ipopt_backend`, :mod:`.lm_backend`, :mod:`.scp_backend`), optionally rescue a rejected
plan with IPOPT, and certify (:mod:`.certificate`): every result, whatever the backend, is
checked against every obstacle given, and a plan that fails the check is replaced by the
stationary trajectory (thesis §3.5.2: it is feasible whenever the start is) and flagged as a
fallback. Many problems at once: :func:`solvers.planner.batching.plan_batch`.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Sequence
from typing import Generic, TypeVar

import numpy as np

from solvers.planner.backend import Backend, Iterate
from solvers.planner.context import PlanningContext
from solvers.planner.ipopt_backend import IpoptBackend
from solvers.planner.lm_backend import LMBackend
from solvers.planner.problem import GPPrior, PreparedProblem, bucket_size, join
from solvers.planner.result import PlanResult
from solvers.planner.scp_backend import ScpBackend
from solvers.planner.settings import PlannerSettings
from solvers.planner.warm_start import WarmStartMemory

logger = logging.getLogger(__name__)

T = TypeVar("T")


class _Setting(Generic[T]):
    """A read-only view of one setting: ``planner.clearance`` is ``planner.settings.clearance``."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, planner: SafeTrajectoryPlanner | None, owner: type | None = None) -> T:
        if planner is None:
            return self  # type: ignore[return-value]
        return getattr(planner.settings, self.name)  # type: ignore[no-any-return]

    def __set__(self, planner: SafeTrajectoryPlanner, value: object) -> None:
        raise AttributeError(
            f"planner settings are read-only ({self.name}); build a new planner, e.g. "
            f"SafeTrajectoryPlanner(**{{**planner.settings.to_kwargs(), {self.name!r}: ...}})"
        )


def build_backend(context: PlanningContext) -> Backend:
    """The backend named by ``context.settings.backend``."""
    name = context.settings.backend
    if name == "ipopt":
        return IpoptBackend(context)
    if name == "lm":
        return LMBackend(context)
    return ScpBackend(context)


class SafeTrajectoryPlanner:
    """Plan N waypoints from a start towards a subgoal that keep eps' from every obstacle.

    The keyword arguments are those of :class:`~solvers.planner.settings.PlannerSettings`,
    where each is documented (and the keys of ``conf/planner/*.yaml``); they are validated there
    (``ValueError`` for a bad value) and readable here as attributes (``planner.clearance``).

    Attributes:
        settings: The validated settings (read-only; build a new planner to change them).
        context: GP prior, reach and certificate derived from the settings.
        solver: The backend.
        rescue_solver: IPOPT when ``rescue_backend="ipopt"`` and the backend is LM or SCP.
        memory: The previous plan, for the warm start.

    A planner pickles without its compiled solvers (each backend drops them and rebuilds them
    lazily), so it can be sent to vectorised-environment worker processes.
    """

    backend = _Setting[str]()
    n_waypoints = _Setting[int]()
    clearance = _Setting[float]()
    max_obstacles = _Setting[int]()
    dt = _Setting[float]()
    sigma_smooth = _Setting[float]()
    smooth_weight = _Setting[float]()
    continuous = _Setting[bool]()
    goal_tolerance = _Setting[float]()
    feasibility_margin = _Setting[float]()
    lm_iterations = _Setting[int]()
    lm_lambda = _Setting[float]()
    lm_adaptive = _Setting[bool]()
    lm_lambda_max = _Setting[float]()
    lm_obstacle_weight = _Setting[float]()
    lm_budget_weight = _Setting[float]()
    lm_margin = _Setting[float]()
    lm_damping = _Setting[float]()
    ipopt_max_iter = _Setting[int]()
    ipopt_first_max_iter = _Setting[int]()
    ipopt_options = _Setting[dict[str, object]]()
    scp_max_iterations = _Setting[int]()
    scp_trust_region = _Setting[float]()
    rescue_backend = _Setting[str | None]()

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
        self._build(PlannerSettings(
            backend=backend, n_waypoints=n_waypoints, clearance=clearance,
            max_obstacles=max_obstacles, dt=dt, sigma_smooth=sigma_smooth,
            smooth_weight=smooth_weight, continuous=continuous, goal_tolerance=goal_tolerance,
            feasibility_margin=feasibility_margin, lm_iterations=lm_iterations,
            lm_lambda=lm_lambda, lm_adaptive=lm_adaptive, lm_lambda_max=lm_lambda_max,
            lm_obstacle_weight=lm_obstacle_weight, lm_budget_weight=lm_budget_weight,
            lm_margin=lm_margin, lm_damping=lm_damping, ipopt_max_iter=ipopt_max_iter,
            ipopt_first_max_iter=ipopt_first_max_iter, ipopt_options=ipopt_options,
            scp_max_iterations=scp_max_iterations, scp_trust_region=scp_trust_region,
            rescue_backend=rescue_backend,
        ))

    @classmethod
    def from_settings(cls, settings: PlannerSettings) -> SafeTrajectoryPlanner:
        """A planner with these settings (no previous plan, nothing compiled yet)."""
        planner = cls.__new__(cls)
        planner._build(settings)
        return planner

    def _build(self, settings: PlannerSettings) -> None:
        self.settings = settings
        self.context = PlanningContext(settings)
        self.solver: Backend = build_backend(self.context)
        self.rescue_solver: IpoptBackend | None = (
            IpoptBackend(self.context) if settings.rescue_backend == "ipopt" else None
        )
        self.memory = WarmStartMemory(settings.dt)

    @property
    def prior(self) -> GPPrior:
        """The GP prior of Eq. 3.6."""
        return self.context.prior

    @property
    def reach_radii(self) -> np.ndarray:
        """Per-waypoint reach under the smoothness budget (N,)."""
        return self.context.reach_radii

    @property
    def reach(self) -> float:
        """Farthest any waypoint of an admissible plan can get from the start (m)."""
        return self.context.reach

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
        prep = self.context.prepare(start, subgoal, obstacles)
        warm = self.memory.guess(prep) if warm_start else None
        try:
            plan = self.solver.solve(prep, warm)
        except Exception as error:  # a solver crash must not end a training run: fall back
            logger.warning("planner backend %s failed: %r", self.backend, error)
            plan = Iterate(np.zeros(self.prior.n_var), f"error: {error}", 0, failed=True)
        certificate = self.context.certificate
        if self.rescue_solver is not None and (plan.failed or not certificate.passes(prep, plan.z)):
            plan = self._rescue(prep, plan)
        result = certificate.certify(prep, plan, backend=self.backend, tic=tic)
        result = dataclasses.replace(
            result, smoothness=self.prior.smoothness(join(result.waypoints - prep.start,
                                                          result.velocities)),
            smoothness_budget=self.settings.sigma_smooth)
        self.memory.remember(prep.start, prep.start + prep.goal, result.waypoints)
        return result

    def warmup(self) -> SafeTrajectoryPlanner:
        """Build every compiled solver now (one per obstacle-slot count) instead of on first use,
        the rescue's cold IPOPT programs included."""
        counts = sorted({bucket_size(k, self.max_obstacles) for k in range(self.max_obstacles + 1)})
        self.solver.warmup(counts)
        if self.rescue_solver is not None:
            self.rescue_solver.warmup(counts, attempts=("cold",))
        return self

    def _rescue(self, prep: PreparedProblem, failed: Iterate) -> Iterate:
        """IPOPT's plan for a problem whose LM / SCP plan failed the certificate, or the
        failed plan when IPOPT fails too (then the certificate falls back)."""
        assert self.rescue_solver is not None
        try:
            rescue = self.rescue_solver.solve(prep, None)
        except Exception as error:  # as in plan: a solver crash must not end a run
            logger.warning("planner rescue by ipopt failed: %r", error)
            return failed
        iterations = failed.iterations + rescue.iterations
        if not self.context.certificate.passes(prep, rescue.z):
            return Iterate(failed.z, f"{failed.status}; ipopt rescue: {rescue.status}",
                           iterations, failed.multiplier, failed.failed)
        return Iterate(rescue.z, f"rescued by ipopt ({failed.status}): {rescue.status}",
                       iterations, rescued=True)

    def __repr__(self) -> str:
        return f"SafeTrajectoryPlanner({self.settings!r})"
