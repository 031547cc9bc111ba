"""The planning problem's settings (thesis §3.5.2, Eqs. 3.3-3.7): what every backend solves.

:class:`ProblemSettings` is where each of the problem's keys is defined: the planner takes it
whole (``SafeTrajectoryPlanner(problem=ProblemSettings(...))``), and ``conf/planner/_base.yaml``'s
``problem:`` node mirrors its fields and defaults (a test checks that they are equal); each
backend's knobs live in its own settings class (:mod:`solvers.planner.backends`). Every value
is checked once, when the object is built: ``ValueError`` names the key and the value.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from solvers.planner.validation import count, flag, non_negative, positive, set_field

_POSITIVE = ("dt", "sigma_smooth", "goal_tolerance")
_NON_NEGATIVE = ("clearance", "smooth_weight", "feasibility_margin")
_COUNTS = {"n_waypoints": 3, "max_obstacles": 1}


@dataclass(frozen=True)
class ProblemSettings:
    """The problem of Eqs. 3.3-3.7, validated.

    Attributes:
        n_waypoints: N, waypoints including the start (thesis: 30).
        clearance: eps' (thesis: 0.5 m); an obstacle with radius r needs eps' + r (Eq. 3.7).
        max_obstacles: Most obstacles given to a backend (the nearest reachable ones are kept;
            the certificate checks all).
        dt: Time between waypoints of the GP prior (s); with ``Q_c = I`` only ``sigma_smooth dt^-3``
            matters (the public code's horizon of 10 s over 29 intervals by default).
        sigma_smooth: Smoothness budget ``h_smooth <= sigma_smooth`` (Eqs. 3.3, 3.6). The farthest
            any waypoint can get is ``sqrt(sigma_smooth T^3 / 3)``, T = (N - 1) dt: 4 m by default.
        smooth_weight: rho, a small weight on ``h_smooth`` added to the objective of every
            backend: among plans that get equally close to the subgoal it picks the smoothest, and
            it makes the problem strictly convex away from obstacles.
        continuous: Also keep the clearance along every segment between waypoints.
        goal_tolerance: ``reached_subgoal`` is ``||x_N - subgoal|| < goal_tolerance`` (m).
        feasibility_margin: Extra clearance (m) asked of the hard-constraint backends (IPOPT, SCP),
            which solve to a tolerance; the certificate checks the exact clearance.

    Raises:
        ValueError: A non-finite or out-of-range number, a non-integer count or a flag that is
            not a boolean.
    """

    n_waypoints: int = 30
    clearance: float = 0.5
    max_obstacles: int = 16
    dt: float = 10.0 / 29.0
    sigma_smooth: float = 0.048
    smooth_weight: float = 0.01
    continuous: bool = False
    goal_tolerance: float = 0.05
    feasibility_margin: float = 1e-5

    def __post_init__(self) -> None:
        for name in _POSITIVE:
            set_field(self, name, positive(name, getattr(self, name)))
        for name in _NON_NEGATIVE:
            set_field(self, name, non_negative(name, getattr(self, name)))
        for name, least in _COUNTS.items():
            set_field(self, name, count(name, getattr(self, name), least))
        set_field(self, "continuous", flag("continuous", self.continuous))


def problem_keys() -> tuple[str, ...]:
    """The problem's keys, in order (the ``problem:`` node of ``conf/planner/_base.yaml``)."""
    return tuple(f.name for f in fields(ProblemSettings))
