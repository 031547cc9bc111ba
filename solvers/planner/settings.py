"""The planner's settings: the problem's, one backend's and the rescue's (thesis §3.5.2).

:class:`PlannerSettings` is what a :class:`solvers.planner.SafeTrajectoryPlanner` is built from:
a :class:`~solvers.planner.problem.settings.ProblemSettings` (Eqs. 3.3-3.7), the settings of
exactly one backend (:class:`~solvers.planner.backends.ipopt.IpoptSettings`,
:class:`~solvers.planner.backends.lm.LMSettings` or
:class:`~solvers.planner.backends.scp.SCPSettings`) and, optionally, the IPOPT settings of the
rescue. Each part validates itself when built (``ValueError`` naming the key and the value).

Runs saved before the settings were split (flat nodes and pickles) are read by
:mod:`solvers.planner.legacy`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from solvers.planner.backends import BACKEND_SETTINGS, BACKENDS
from solvers.planner.backends.ipopt import IpoptSettings
from solvers.planner.backends.lm import LMSettings
from solvers.planner.backends.scp import SCPSettings
from solvers.planner.problem.settings import ProblemSettings
from solvers.planner.validation import set_field

#: The settings of one backend.
AnyBackendSettings = IpoptSettings | LMSettings | SCPSettings


def backend_settings(value: object) -> AnyBackendSettings:
    """A backend's settings from its name (its defaults) or as given.

    Raises:
        ValueError: Neither a backend name nor a backend settings object.
    """
    if isinstance(value, str) and value in BACKEND_SETTINGS:
        return BACKEND_SETTINGS[value]()
    if isinstance(value, IpoptSettings | LMSettings | SCPSettings):
        return value
    raise ValueError(f"backend must be one of {list(BACKENDS)} or an IpoptSettings, LMSettings "
                     f"or SCPSettings object, got {value!r}")


def rescue_settings(value: object) -> IpoptSettings | None:
    """The rescue's IPOPT settings from ``None``, ``"ipopt"`` (IPOPT's defaults) or as given.

    Raises:
        ValueError: Anything else.
    """
    if value is None or isinstance(value, IpoptSettings):
        return value
    if value == "ipopt":
        return IpoptSettings()
    raise ValueError(f"rescue_backend must be None or 'ipopt', got {value!r}")


@dataclass(frozen=True)
class PlannerSettings:
    """Everything a planner is built from, validated.

    Attributes:
        problem: The problem's settings.
        backend: The backend's settings (a name gives that backend's defaults).
        rescue: ``None`` (default) or IPOPT's settings: when the LM or SCP plan fails the
            certificate, solve the same problem with IPOPT (cold, hard constraints) before
            falling back to the stationary plan (docs/planner.md, "Backends"). ``"ipopt"``
            gives IPOPT's defaults. Stored as None with an IPOPT backend, which has nothing to
            rescue with.

    Raises:
        ValueError: ``problem`` is not a :class:`ProblemSettings`, or a bad backend or rescue.
    """

    problem: ProblemSettings = field(default_factory=ProblemSettings)
    backend: AnyBackendSettings = field(default_factory=IpoptSettings)
    rescue: IpoptSettings | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.problem, ProblemSettings):
            raise ValueError(f"problem must be a ProblemSettings, got {self.problem!r}")
        set_field(self, "backend", backend_settings(self.backend))
        rescue = rescue_settings(self.rescue)
        set_field(self, "rescue", None if self.backend.name == "ipopt" else rescue)

    @property
    def rescue_backend(self) -> str | None:
        """``"ipopt"`` when plans are rescued, else None (the ``conf/planner`` key)."""
        return None if self.rescue is None else "ipopt"
