"""One source of defaults: a ``conf/`` node with a ``_target_`` says what its target's Python
signature says, key by key (where the signature has a default). The exceptions below are
deliberate; a value that differs for no listed reason fails."""

from __future__ import annotations

import inspect
from typing import Any

import pytest
from hydra._internal.utils import _locate
from omegaconf import OmegaConf

from semdp.configs import compose_config
from semdp.paths import CONF_DIR

#: (target or a base class of it, key, value) -> why an option file chooses a value other than
#: the Python default.
EXCEPTIONS: dict[tuple[str, str, object], str] = {
    ("solvers.planner.LMSettings", "adaptive", True):
        "planner/lm_adaptive: the thesis' evaluation setting (App. B.2.3) beside fixed lambda",
    ("semdp.algos.lagrangian.Lagrange", "optimizer", "sgd"):
        "algo/lagrange/sgd: the thesis' plain gradient step (Eq. 2.10) beside Adam",
    ("semdp.algos.lagrangian.Lagrange", "lr", 0.01):
        "algo/lagrange/sgd: its step size beta (docs/training.md, 'Learning checks')",
    ("semdp.embedded.goal_reaching.GoalReachingEnv", "keep_cost", True):
        "env/follower_ppo_lag: the low level of the 'SAC + PPO Lag' ablation keeps the costs",
    ("semdp.embedded.goal_reaching.GoalReachingEnv", "include_lidar", True):
        "env/follower_ppo_lag: ... and sees the obstacle LiDAR",
}


def python_defaults(target: Any) -> dict[str, Any]:
    """The defaults of a callable's keyword arguments; a class's from its ``__init__`` and, for
    arguments passed on through ``**kwargs``, from its bases'; an on-policy algorithm's with
    those of the speed-up keys that :func:`semdp.algos.speedups.on_policy_seams` reads."""
    from semdp.algos.on_policy import OnPolicyAlgorithm
    from semdp.algos.speedups import on_policy_seams

    if inspect.isclass(target) and issubclass(target, OnPolicyAlgorithm):
        return {**python_defaults(on_policy_seams), **_signature_defaults(target)}
    return _signature_defaults(target)


def _signature_defaults(target: Any) -> dict[str, Any]:
    """:func:`python_defaults` of the callable's own signature (and its bases')."""
    if not inspect.isclass(target):
        return {name: p.default for name, p in inspect.signature(target).parameters.items()
                if p.default is not inspect.Parameter.empty}
    defaults: dict[str, Any] = {}
    for cls in target.__mro__:
        init = cls.__dict__.get("__init__")
        if init is None:
            continue
        parameters = inspect.signature(init).parameters
        for name, p in parameters.items():
            if p.default is not inspect.Parameter.empty:
                defaults.setdefault(name, p.default)
        if not any(p.kind is p.VAR_KEYWORD for p in parameters.values()):
            break
    return defaults


def _excepted(target: Any, key: str, value: Any) -> bool:
    """Whether :data:`EXCEPTIONS` lists ``key: value`` for ``target`` or a class it derives from."""
    value = tuple(value) if isinstance(value, list) else value
    for (owner, name, chosen) in EXCEPTIONS:
        if name == key and chosen == value:
            cls = _locate(owner)
            if target is cls or (inspect.isclass(target) and issubclass(target, cls)):
                return True
    return False


def _plain(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def mismatches(node: dict[str, Any], where: str = "") -> list[str]:
    """``"<where> <target>.<key>: config X, Python Y"`` for every key of every ``_target_`` node
    in ``node`` whose plain value differs from the target's Python default (interpolations and
    nested objects are not compared; :data:`EXCEPTIONS` are allowed)."""
    found: list[str] = []
    target = node.get("_target_")
    located = _locate(target) if isinstance(target, str) else None
    defaults = python_defaults(located) if located is not None else {}
    for key, value in node.items():
        if isinstance(value, dict):
            found += mismatches(value, f"{where}.{key}")
            continue
        if (key.startswith("_") or key not in defaults or value == "???"
                or (isinstance(value, str) and "${" in value)
                or _excepted(located, key, value)):
            continue
        if _plain(value) != _plain(defaults[key]):
            found.append(f"{where} {target}.{key}: config {value!r}, Python {defaults[key]!r}")
    return found


def _target_files() -> list[str]:
    """The files that define a target node (a ``_target_`` in their text); the presets
    (``experiment/``, ``method/``, ``budget/``) that only choose values of others' are not."""
    return sorted(str(p.relative_to(CONF_DIR).with_suffix(""))
                  for p in CONF_DIR.rglob("*.yaml")
                  if "hydra" not in p.parts and "_target_:" in p.read_text())


@pytest.mark.parametrize("name", _target_files())
def test_every_target_node_has_its_python_defaults(name: str) -> None:
    """Each file composed as Hydra composes it (the bases of its defaults list included); a
    file that only composes inside the training config (it picks a robot, or sets global keys)
    as it is written."""
    try:
        node = OmegaConf.to_container(compose_config(name), resolve=False)
    except Exception:  # a file that composes only inside the training config
        node = OmegaConf.to_container(OmegaConf.load(CONF_DIR / f"{name}.yaml"), resolve=False)
    found = mismatches(node)
    assert not found, "config values that differ from the Python defaults:\n" + "\n".join(found)


def test_a_planted_mismatch_is_found() -> None:
    node = {"_target_": "solvers.planner.SafeTrajectoryPlanner",
            "problem": {"_target_": "solvers.planner.ProblemSettings", "clearance": 0.6,
                        "n_waypoints": 30},
            "backend": {"_target_": "solvers.planner.LMSettings", "native": False,
                        "iterations": "${x}", "adaptive": True}}
    assert mismatches(node) == [
        ".problem solvers.planner.ProblemSettings.clearance: config 0.6, Python 0.5",
        ".backend solvers.planner.LMSettings.native: config False, Python True",
    ]
    ppo = {"_target_": "semdp.algos.PPOLag", "vectorization": "sync", "gradients": "written"}
    assert mismatches(ppo) == [" semdp.algos.PPOLag.vectorization: config 'sync', Python 'auto'"]
    shield = {"_target_": "semdp.embedded.shield.SafetyShield", "kernel": "compiled"}
    assert mismatches(shield) == [" semdp.embedded.shield.SafetyShield.kernel: config "
                                  "'compiled', Python 'native'"]
