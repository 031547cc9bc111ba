"""The planner's files of earlier versions, read in one place: saved config nodes and pickles.

Only loading calls this module (semdp's run-config loader and checkpoint unpickler,
``semdp/legacy.py``, or :func:`loads` on a planner pickle); the planner's classes know nothing of
earlier versions.

Config nodes (:func:`planner_node`). A ``SafeTrajectoryPlanner`` node saved

* before the settings were split holds one flat node: ``backend: lm`` (a name), the problem's
  keys, ``lm_*``, ``ipopt_*`` and ``scp_*`` keys (:data:`FLAT_BACKEND_KEYS`) and
  ``rescue_backend``;
* before the problem became one object holds the problem's keys beside its ``backend:`` node;

both become today's node, ``problem:`` (:class:`~solvers.planner.ProblemSettings`), ``backend:``
(the backend's settings) and ``rescue_backend``. The chosen backend's keys become its settings,
the ``ipopt_*`` keys also configure the IPOPT rescue, the other backends' keys are dropped
(``lm_margin`` also widened the obstacle selection of IPOPT and SCP, which now add
:data:`~solvers.planner.backends.base.SELECTION_SLACK`, its default).

Pickles (:class:`Unpickler`, :func:`find_class`). Training checkpoints pickle the vector env,
planners included. A planner pickled before the split holds the flat settings object, a
``PlanningContext`` and backend objects of modules that no longer exist (:data:`REMOVED`): those
are read as stand-ins that keep their pickled state (:class:`RemovedClass`), the flat settings
through :func:`settings_from_flat`, and the planner keeps the pickled GP prior (the numbers the
run planned with), so a resumed run plans as before.
"""

from __future__ import annotations

import io
import pickle
from collections.abc import Callable, Mapping
from typing import Any

from solvers.planner.backends import BACKEND_SETTINGS
from solvers.planner.planner import SafeTrajectoryPlanner
from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.settings import ProblemSettings, problem_keys
from solvers.planner.settings import PlannerSettings

#: The flat (pre-split) backend keys: flat key -> (backend, key of its settings class).
FLAT_BACKEND_KEYS: dict[str, tuple[str, str]] = {
    "lm_lambda": ("lm", "lambda_"),
    **{f"{backend}_{key}": (backend, key) for backend, keys in (
        ("lm", ("iterations", "adaptive", "lambda_max", "obstacle_weight", "budget_weight",
                "margin", "damping")),
        ("ipopt", ("max_iter", "first_max_iter", "options")),
        ("scp", ("max_iterations", "trust_region")),
    ) for key in keys},
}
PLANNER_TARGET = "solvers.planner.SafeTrajectoryPlanner"
PROBLEM_TARGET = "solvers.planner.ProblemSettings"
#: The ``_target_`` of each backend's settings node.
SETTINGS_TARGETS: dict[str, str] = {
    name: f"solvers.planner.{cls.__name__}" for name, cls in BACKEND_SETTINGS.items()
}


# ---------------------------------------------------------------- config nodes
def is_old_planner_node(node: Mapping[str, object]) -> bool:
    """Whether a ``SafeTrajectoryPlanner`` node is of an earlier form (no ``problem:`` node,
    a problem key beside it, or a backend given by name)."""
    return ("problem" not in node or any(key in node for key in problem_keys())
            or isinstance(node.get("backend", "ipopt"), str))


def planner_node(node: Mapping[str, object]) -> dict[str, object]:
    """Today's form of a ``SafeTrajectoryPlanner`` node of any earlier form (see the module
    docstring); values, interpolations included, are moved as they are.

    Raises:
        ValueError: An unknown backend name, or flat backend keys beside a backend node.
    """
    old = dict(node)
    problem = dict(old.pop("problem", None) or {"_target_": PROBLEM_TARGET})  # type: ignore[call-overload]
    problem.update({key: old.pop(key) for key in problem_keys() if key in old})
    flat = {key: old.pop(key) for key in list(old) if key in FLAT_BACKEND_KEYS}
    backend = old.pop("backend", "ipopt")
    rescue = old.pop("rescue_backend", None)
    if isinstance(backend, str):
        if backend not in SETTINGS_TARGETS:
            raise ValueError(f"backend must be one of {list(SETTINGS_TARGETS)}, got {backend!r}")

        def keys_of(name: str) -> dict[str, object]:
            return {setting: flat[key] for key, (owner, setting) in FLAT_BACKEND_KEYS.items()
                    if owner == name and key in flat}

        backend_name = backend
        backend = {"_target_": SETTINGS_TARGETS[backend_name], **keys_of(backend_name)}
        if rescue == "ipopt" and backend_name != "ipopt" and keys_of("ipopt"):
            rescue = {"_target_": SETTINGS_TARGETS["ipopt"], **keys_of("ipopt")}
    elif flat:
        raise ValueError(f"flat backend keys {sorted(flat)} beside a backend node")
    return {"_target_": old.pop("_target_", PLANNER_TARGET), **old, "problem": problem,
            "backend": backend, "rescue_backend": rescue}


def _built(node: object) -> Any:
    """The settings object of a node of :func:`planner_node` (plain values pass through)."""
    if not isinstance(node, Mapping):
        return node
    classes = {PROBLEM_TARGET: ProblemSettings,
               **{SETTINGS_TARGETS[name]: cls for name, cls in BACKEND_SETTINGS.items()}}
    kwargs = {key: value for key, value in node.items() if key != "_target_"}
    return classes[str(node["_target_"])](**kwargs)


def settings_from_flat(flat: Mapping[str, object]) -> PlannerSettings:
    """The settings of a flat, pre-split settings object (or node).

    Raises:
        ValueError: An unknown key or a bad value (the message names it).
    """
    known = {"backend", "rescue_backend", *problem_keys(), *FLAT_BACKEND_KEYS}
    unknown = sorted(set(flat) - known)
    if unknown:
        raise ValueError(f"unknown planner settings {unknown}; known: {sorted(known)}")
    node = planner_node(flat)
    return PlannerSettings(_built(node["problem"]), _built(node["backend"]),
                           _built(node["rescue_backend"]))


# ---------------------------------------------------------------- pickles
#: The classes of the removed modules that a pickled planner can name.
REMOVED: dict[str, tuple[str, ...]] = {
    "solvers.planner.context": ("PlanningContext",),
    "solvers.planner.certificate": ("Certificate",),
    "solvers.planner.backend": ("Iterate",),
    "solvers.planner.ipopt_backend": ("IpoptBackend",),
    "solvers.planner.ipopt": ("IpoptProgram",),
    "solvers.planner.lm_backend": ("LMBackend",),
    "solvers.planner.lm": ("LMWeights", "LMKernel"),
    "solvers.planner.scp_backend": ("ScpBackend",),
    "solvers.planner.scp": ("ScpProgram",),
}


class RemovedClass:
    """An object of a removed planner class, kept as its pickled state (:attr:`state`)."""

    state: object = None

    def __init__(self, *args: object, **kwargs: object) -> None:
        cls = type(self)
        raise TypeError(f"{cls.__module__}.{cls.__qualname__} no longer exists (the planner's "
                        "settings were split); it is only read from old pickles")

    def __setstate__(self, state: object) -> None:
        self.state = state


_STAND_INS: dict[tuple[str, str], type] = {
    (module, name): type(name, (RemovedClass,), {"__module__": module, "__qualname__": name})
    for module, names in REMOVED.items() for name in names
}


def upgrading(cls: type, upgrade: Callable[[dict[str, Any]], dict[str, Any]]) -> type:
    """A stand-in for ``cls`` in an unpickler: the object it makes is given
    ``upgrade(state)`` and becomes a plain ``cls`` (no trace of the upgrade is left)."""

    def __setstate__(self: Any, state: dict[str, Any]) -> None:
        object.__setattr__(self, "__class__", cls)
        state = upgrade(dict(state))
        if hasattr(cls, "__setstate__"):
            cls.__setstate__(self, state)
        else:
            self.__dict__.update(state)

    return type(cls.__name__, (cls,), {"__setstate__": __setstate__,
                                       "__module__": cls.__module__})


def _settings_state(state: dict[str, Any]) -> dict[str, Any]:
    return state if "problem" in state else dict(settings_from_flat(state).__dict__)


def _planner_state(state: dict[str, Any]) -> dict[str, Any]:
    context = state["context"]
    if not isinstance(context, ProblemContext):  # a PlanningContext: keep its pickled prior
        pickled = context.state if isinstance(context, RemovedClass) else None
        prior = pickled.get("prior") if isinstance(pickled, dict) else None
        state["context"] = ProblemContext(state["settings"].problem,
                                          prior if isinstance(prior, GPPrior) else None)
    return state


_UPGRADES: dict[tuple[str, str], type] = {
    ("solvers.planner.settings", "PlannerSettings"): upgrading(PlannerSettings, _settings_state),
    ("solvers.planner.planner", "SafeTrajectoryPlanner"):
        upgrading(SafeTrajectoryPlanner, _planner_state),
}


def find_class(module: str, name: str) -> type | None:
    """The class an unpickler is to use for ``module.name`` of an old planner pickle (a
    stand-in or an upgrading class), or None for the ordinary lookup."""
    return _STAND_INS.get((module, name)) or _UPGRADES.get((module, name))


class Unpickler(pickle.Unpickler):
    """An unpickler that reads the planner's old pickles (:func:`find_class`)."""

    def find_class(self, module: str, name: str) -> Any:
        return find_class(module, name) or super().find_class(module, name)


def loads(data: bytes) -> Any:
    """``pickle.loads`` that reads the planner's old pickles."""
    return Unpickler(io.BytesIO(data)).load()
