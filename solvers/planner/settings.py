"""The planner's settings: one frozen, validated object (thesis §3.5.2, App. B.2.3).

:class:`PlannerSettings` holds exactly the constructor keywords of
:class:`solvers.planner.SafeTrajectoryPlanner` (and so the keys of ``conf/planner/*.yaml``). It
checks every value once, when it is built, and raises ``ValueError`` naming the offending key
and value; the planner and its backends then read it without further checks.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields

import numpy as np

#: Names of the solver backends.
BACKENDS: tuple[str, ...] = ("ipopt", "lm", "scp")
#: Backends that can rescue a plan the certificate rejects (None: no rescue).
RESCUE_BACKENDS: tuple[str | None, ...] = (None, "ipopt")

_POSITIVE = (
    "dt", "sigma_smooth", "lm_lambda", "lm_lambda_max", "lm_obstacle_weight", "lm_budget_weight",
    "lm_damping", "scp_trust_region", "goal_tolerance",
)
_NON_NEGATIVE = ("clearance", "smooth_weight", "feasibility_margin", "lm_margin")
#: Integer settings and their least allowed value.
_COUNTS = {
    "n_waypoints": 3, "max_obstacles": 1, "lm_iterations": 1, "ipopt_max_iter": 1,
    "ipopt_first_max_iter": 0, "scp_max_iterations": 1,
}
_FLAGS = ("continuous", "lm_adaptive")


@dataclass(frozen=True)
class PlannerSettings:
    """Every setting of the safe trajectory planner, validated.

    Attributes:
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
        ipopt_first_max_iter: Iteration cap of the first attempt from the guess / previous plan
            (0: skip it).
        ipopt_options: IPOPT options merged over :data:`solvers.planner.ipopt.IPOPT_OPTIONS`
            (None is stored as an empty dict).
        scp_max_iterations: QP solves at most.
        scp_trust_region: Half-width of the SCP trust-region box.
        rescue_backend: ``None`` (default) or ``"ipopt"``: when the LM or SCP plan fails the
            certificate, solve the same problem with IPOPT (cold, hard constraints) before
            falling back to the stationary plan (solvers/README.md, "Rescue"). Stored as None
            with ``backend="ipopt"``, which has nothing to rescue with.

    Raises:
        ValueError: An unknown backend or rescue backend, a non-finite or out-of-range number,
            a non-integer count, a flag that is not a boolean, ``lm_lambda > lm_lambda_max`` or
            ``ipopt_options`` that is not a mapping.
    """

    backend: str = "ipopt"
    n_waypoints: int = 30
    clearance: float = 0.5
    max_obstacles: int = 16
    dt: float = 10.0 / 29.0
    sigma_smooth: float = 0.048
    smooth_weight: float = 0.01
    continuous: bool = False
    goal_tolerance: float = 0.05
    feasibility_margin: float = 1e-5
    lm_iterations: int = 10
    lm_lambda: float = 1.0
    lm_adaptive: bool = False
    lm_lambda_max: float = 1024.0
    lm_obstacle_weight: float = 1000.0
    lm_budget_weight: float = 100.0
    lm_margin: float = 0.02
    lm_damping: float = 1e-4
    ipopt_max_iter: int = 200
    ipopt_first_max_iter: int = 30
    # a dict is not hashable: equal settings still hash equal without it
    ipopt_options: Mapping[str, object] | None = field(default=None, hash=False)
    scp_max_iterations: int = 30
    scp_trust_region: float = 1.0
    rescue_backend: str | None = None

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {list(BACKENDS)}, got {self.backend!r}")
        if self.rescue_backend not in RESCUE_BACKENDS:
            raise ValueError(
                f"rescue_backend must be None or 'ipopt', got {self.rescue_backend!r}"
            )
        for name in _POSITIVE:
            self._set(name, _number(name, getattr(self, name), "> 0", lambda v: v > 0))
        for name in _NON_NEGATIVE:
            self._set(name, _number(name, getattr(self, name), ">= 0", lambda v: v >= 0))
        for name, least in _COUNTS.items():
            self._set(name, _count(name, getattr(self, name), least))
        for name in _FLAGS:
            self._set(name, _flag(name, getattr(self, name)))
        if self.lm_lambda > self.lm_lambda_max:
            raise ValueError(
                f"lm_lambda ({self.lm_lambda}) must be <= lm_lambda_max ({self.lm_lambda_max})"
            )
        options = self.ipopt_options
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(f"ipopt_options must be a mapping or None, got {options!r}")
        self._set("ipopt_options", {str(k): v for k, v in (options or {}).items()})
        if self.backend == "ipopt":
            self._set("rescue_backend", None)

    def _set(self, name: str, value: object) -> None:
        object.__setattr__(self, name, value)

    def to_kwargs(self) -> dict[str, object]:
        """The constructor keywords that rebuild these settings."""
        return asdict(self)


def setting_names() -> tuple[str, ...]:
    """Names of the settings, in constructor order (the keys of ``conf/planner/*.yaml``)."""
    return tuple(f.name for f in fields(PlannerSettings))


def _number(name: str, value: object, bound: str, ok: Callable[[float], bool]) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
    number = float(value)
    if not math.isfinite(number) or not ok(number):
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
    return number


def _count(name: str, value: object, least: int) -> int:
    integral = isinstance(value, numbers.Integral) or (
        isinstance(value, numbers.Real)
        and math.isfinite(float(value))
        and float(value).is_integer()
    )
    if isinstance(value, bool) or not integral or int(value) < least:  # type: ignore[call-overload]
        raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)  # type: ignore[call-overload]


def _flag(name: str, value: object) -> bool:
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral) and int(value) in (0, 1):
        return bool(value)
    raise ValueError(f"{name} must be a boolean, got {value!r}")
