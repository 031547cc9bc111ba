"""The planner's settings: the problem's, one backend's and the rescue's (thesis §3.5.2).

:class:`PlannerSettings` is what a :class:`solvers.planner.SafeTrajectoryPlanner` is built from:
a :class:`~solvers.planner.problem.settings.ProblemSettings` (Eqs. 3.3-3.7), the settings of
exactly one backend (:class:`~solvers.planner.backends.ipopt.IpoptSettings`,
:class:`~solvers.planner.backends.lm.LMSettings` or
:class:`~solvers.planner.backends.scp.SCPSettings`) and, optionally, the IPOPT settings of the
rescue. Each part validates itself when built (``ValueError`` naming the key and the value).

Runs saved before the settings were split hold one flat node (``backend: lm``,
``lm_iterations: 10``, ``ipopt_max_iter: 200``, ...) in their ``config.yaml``, and their
checkpoints pickle the flat settings object: :meth:`PlannerSettings.from_flat` is the one place
that converts those (the planner's constructor and unpickling both use it).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from solvers.planner.backends import BACKEND_SETTINGS, BACKENDS
from solvers.planner.backends.ipopt import IpoptSettings
from solvers.planner.backends.lm import LMSettings
from solvers.planner.backends.scp import SCPSettings
from solvers.planner.problem.settings import ProblemSettings, problem_keys
from solvers.planner.validation import set_field

#: The settings of one backend.
AnyBackendSettings = IpoptSettings | LMSettings | SCPSettings

#: The flat (pre-split) backend keys: flat key -> (backend, key of its settings class).
FLAT_BACKEND_KEYS: dict[str, tuple[str, str]] = {
    "lm_iterations": ("lm", "iterations"),
    "lm_lambda": ("lm", "lambda_"),
    "lm_adaptive": ("lm", "adaptive"),
    "lm_lambda_max": ("lm", "lambda_max"),
    "lm_obstacle_weight": ("lm", "obstacle_weight"),
    "lm_budget_weight": ("lm", "budget_weight"),
    "lm_margin": ("lm", "margin"),
    "lm_damping": ("lm", "damping"),
    "ipopt_max_iter": ("ipopt", "max_iter"),
    "ipopt_first_max_iter": ("ipopt", "first_max_iter"),
    "ipopt_options": ("ipopt", "options"),
    "scp_max_iterations": ("scp", "max_iterations"),
    "scp_trust_region": ("scp", "trust_region"),
}


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

    @classmethod
    def from_flat(cls, flat: Mapping[str, object]) -> PlannerSettings:
        """The settings of a flat, pre-split settings node or object.

        ``flat`` holds the keywords the planner took before its settings were split:
        ``backend`` (a name), the problem's keys, ``lm_*``, ``ipopt_*`` and ``scp_*`` keys
        (:data:`FLAT_BACKEND_KEYS`) and ``rescue_backend`` (``None`` or ``"ipopt"``); missing
        keys take their defaults. Every backend's keys are validated, as they were; the chosen
        backend's become its settings and the ``ipopt_*`` keys also configure the IPOPT rescue.
        The other backends' keys are dropped (``lm_margin`` also widened the obstacle selection
        of IPOPT and SCP, which now add
        :data:`~solvers.planner.backends.base.SELECTION_SLACK`, its default).

        Raises:
            ValueError: An unknown key or a bad value (the message names it).
        """
        known = {"backend", "rescue_backend", *problem_keys(), *FLAT_BACKEND_KEYS}
        unknown = sorted(set(flat) - known)
        if unknown:
            raise ValueError(f"unknown planner settings {unknown}; known: {sorted(known)}")
        name = flat.get("backend", "ipopt")
        if not isinstance(name, str) or name not in BACKENDS:
            raise ValueError(f"backend must be one of {list(BACKENDS)}, got {name!r}")
        keywords: dict[str, dict[str, object]] = {backend: {} for backend in BACKENDS}
        for key, (backend, setting) in FLAT_BACKEND_KEYS.items():
            if key in flat:
                keywords[backend][setting] = flat[key]
        built = {}
        for backend, kwargs in keywords.items():
            try:
                built[backend] = BACKEND_SETTINGS[backend](**kwargs)  # type: ignore[arg-type]
            except ValueError as error:
                raise ValueError(f"{backend} settings ({backend}_* keys): {error}") from None
        problem = ProblemSettings(**{k: flat[k] for k in problem_keys() if k in flat})  # type: ignore[arg-type]
        rescue = rescue_settings(flat.get("rescue_backend"))
        return cls(problem, built[name], built["ipopt"] if rescue is not None else None)

    def __setstate__(self, state: dict[str, object]) -> None:
        """Unpickle; a flat settings object pickled before the split goes through
        :meth:`from_flat`."""
        if "problem" not in state:
            state = dict(PlannerSettings.from_flat(state).__dict__)
        self.__dict__.update(state)
