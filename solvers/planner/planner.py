"""``SafeTrajectoryPlanner``: the safe trajectory optimiser of thesis §3.5.2 behind one interface.

Three backends solve the same problem (Eqs. 3.3-3.7, :mod:`solvers.planner.problem`): IPOPT
(hard pairwise constraints), LM (the thesis' penalty form, Eq. 3.8, with Levenberg-Marquardt;
fixed or adaptive lambda, App. B.2.3) and SCP (convex QPs on OSQP with tangent half-spaces), each
in its own module of :mod:`solvers.planner.backends` with its own settings. A plan goes through
four steps: validate and select the obstacles (:mod:`.problem.preparation`), solve (the
backend), optionally rescue a rejected plan with IPOPT, and certify (:mod:`.problem.certificate`):
every result, whatever the backend, is checked against every obstacle given, and a plan that
fails the check is replaced by the stationary trajectory (thesis §3.5.2: it is feasible whenever
the start is) and flagged as a fallback. Many problems at once:
:func:`solvers.planner.batch.plan_batch`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

import numpy as np

from solvers.planner.backends.base import Backend, bucket_size
from solvers.planner.backends.ipopt import IpoptBackend, IpoptSettings
from solvers.planner.problem.certificate import Iterate
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.preparation import PreparedProblem
from solvers.planner.problem.settings import ProblemSettings
from solvers.planner.result import PlanResult
from solvers.planner.settings import AnyBackendSettings, PlannerSettings
from solvers.planner.warm_start import WarmStartMemory

logger = logging.getLogger(__name__)


class SafeTrajectoryPlanner:
    """Plan N waypoints from a start towards a subgoal that keep eps' from every obstacle.

    Args:
        backend: The backend's settings (:class:`~solvers.planner.backends.ipopt.IpoptSettings`,
            :class:`~solvers.planner.backends.lm.LMSettings`,
            :class:`~solvers.planner.backends.scp.SCPSettings`; a ``conf/planner`` file's
            ``backend:`` node) or a backend name (``"ipopt"``, ``"lm"``, ``"scp"``: its
            defaults).
        problem: The problem's settings (:class:`~solvers.planner.problem.settings.
            ProblemSettings`, a ``conf/planner`` file's ``problem:`` node); None: its defaults.
        rescue_backend: None or ``"ipopt"`` (or IPOPT settings): see
            :class:`~solvers.planner.settings.PlannerSettings`.

    Raises:
        ValueError: A bad setting (the message names the key and the value).

    Attributes:
        settings: The validated settings (read-only; build a new planner to change them).
        context: GP prior, reach and certificate derived from the problem's settings.
        solver: The backend.
        rescue_solver: IPOPT when a rescue is set and the backend is LM or SCP.
        memory: The previous plan, for the warm start.

    A planner pickles without its compiled solvers (each backend drops them and rebuilds them
    lazily), so it can be sent to vectorised-environment worker processes.
    """

    def __init__(
        self,
        backend: AnyBackendSettings | str = "ipopt",
        problem: ProblemSettings | None = None,
        rescue_backend: IpoptSettings | str | None = None,
    ) -> None:
        self._build(PlannerSettings(ProblemSettings() if problem is None else problem, backend,
                                    rescue_backend))  # type: ignore[arg-type]

    @classmethod
    def from_settings(cls, settings: PlannerSettings) -> SafeTrajectoryPlanner:
        """A planner with these settings (no previous plan, nothing compiled yet)."""
        planner = cls.__new__(cls)
        planner._build(settings)
        return planner

    def _build(self, settings: PlannerSettings, context: ProblemContext | None = None) -> None:
        self.settings = settings
        self.context = context if context is not None else ProblemContext(settings.problem)
        self.solver: Backend = settings.backend.build(self.context)
        self.rescue_solver: IpoptBackend | None = (
            None if settings.rescue is None else settings.rescue.build(self.context)
        )
        self.memory = WarmStartMemory(settings.problem.dt)

    @property
    def problem(self) -> ProblemSettings:
        """The problem's settings (``settings.problem``)."""
        return self.settings.problem

    @property
    def n_waypoints(self) -> int:
        """N, waypoints of every plan, the start included (:class:`~solvers.planner.Planner`)."""
        return self.settings.problem.n_waypoints

    @property
    def clearance(self) -> float:
        """eps' (m), the certificate's clearance (:class:`~solvers.planner.Planner`)."""
        return self.settings.problem.clearance

    @property
    def backend(self) -> str:
        """The backend's name (``"ipopt"``, ``"lm"``, ``"scp"``); its settings are
        ``settings.backend``."""
        return self.settings.backend.name

    @property
    def rescue_backend(self) -> str | None:
        """``"ipopt"`` when plans the certificate rejects are rescued, else None."""
        return self.settings.rescue_backend

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
        prep = self.context.prepare(start, subgoal, obstacles, reach=self.solver.selection_reach)
        warm = self.memory.guess(prep) if warm_start else None
        try:
            plan = self.solver.solve(prep, warm)
        except Exception as error:  # a solver crash must not end a training run: fall back
            logger.warning("planner backend %s failed: %r", self.backend, error)
            plan = Iterate(np.zeros(self.prior.n_var), f"error: {error}", 0, failed=True)
        certificate = self.context.certificate
        if self.rescue_solver is not None and (
                plan.failed or not (plan.passed or certificate.passes(prep, plan.z))):
            plan = self._rescue(prep, plan)
        result = certificate.certify(prep, plan, backend=self.backend, tic=tic,
                                     smoothness=self.prior.smoothness,
                                     smoothness_budget=self.problem.sigma_smooth)
        self.memory.remember(prep.start, prep.start + prep.goal, result.waypoints)
        return result

    def warmup(self) -> SafeTrajectoryPlanner:
        """Build every compiled solver now (one per obstacle-slot count) instead of on first use,
        the rescue's cold IPOPT programs included."""
        most = self.problem.max_obstacles
        counts = sorted({bucket_size(k, most) for k in range(most + 1)})
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

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, object]:
        """The settings, the problem's context (its GP prior as computed here) and the warm-start
        memory; the backends are rebuilt on unpickling, without compiled solvers."""
        return {"settings": self.settings, "context": self.context, "memory": self.memory}

    def __setstate__(self, state: dict[str, object]) -> None:
        self._build(state["settings"], state["context"])  # type: ignore[arg-type]
        self.memory = state["memory"]  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"SafeTrajectoryPlanner({self.settings!r})"

