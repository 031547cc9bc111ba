"""semdp's files of earlier versions, read in one place: saved run configs and checkpoints.

Only loading calls this module: :func:`semdp.run_config.load_run_config` passes every saved
``config.yaml`` through :func:`upgrade_run_config`, and
:func:`semdp.common.checkpoint_files.load_checkpoint_file` unpickles through
:class:`Unpickler`. The classes that run know nothing of earlier versions: the configs and
objects they are given are today's.

Run configs (:func:`upgrade_run_config`), in place:

* a ``_target_`` that moved (:data:`RENAMED_TARGETS`) names the class of today;
* a Safety-Embedded MDP wrapper saved with its planner and follower by name (``planner:
  lm_adaptive`` with ``planner_kwargs``; ``follower: auto``, ``<robot>`` or
  ``<robot>_ppo_lag``) gets the ``conf`` nodes that hold them now;
* a planner node of an earlier form (the flat keys of before the settings were split, the
  problem's keys beside ``backend``) gets today's form, ``problem:`` / ``backend:`` /
  ``rescue_backend`` (:func:`solvers.planner.legacy.planner_node`);
* the filter's ``lidar_bearing_bound: true / false`` (runs recorded before the aliasing bound)
  reads ``bin`` / ``none`` (:data:`RECORDED_BOUNDS`);
* a wrapper or filter node without ``gremlins`` (runs recorded before the moving-gremlin
  certificate) gets ``orbit``, the whole orbit discs it ran with;
* an on-policy algorithm node without ``gradients`` (runs recorded before the written-out
  derivatives) gets ``autograd``, the derivatives it ran with.

Checkpoints (:class:`Unpickler`): the planner's old pickles (:mod:`solvers.planner.legacy`),
classes that moved (:data:`RENAMED_TARGETS`), objects pickled before one of their attributes
existed, which get the value they ran with (:data:`ADDED_ATTRIBUTES`), and the boolean bearing
bounds. Sub-envs that a rollout helper pickled into the checkpoint (``pickle.loads`` of a blob)
are read by the same unpickler.
"""

from __future__ import annotations

import functools
import io
import pickle
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from semdp.configs import compose_node

#: ``_target_`` (and pickled class) of earlier versions -> the same object today.
RENAMED_TARGETS: dict[str, str] = {
    "semdp.common.lagrange.Lagrange": "semdp.algos.lagrangian.Lagrange",
    "semdp.common.lagrange.PIDLagrange": "semdp.algos.pid_lagrange.PIDLagrange",
    "semdp.common.self_paced.SelfPacedThresholds": "semdp.algos.sp_ppo_lag.SelfPacedThresholds",
    "semdp.embedded.artifacts.after_training": "semdp.reporting.semdp_run.after_training",
}
#: Modules of earlier versions -> today's (``semdp.algos.fast`` split by mechanism, SAC's
#: modules gathered in ``semdp.algos.sac``).
RENAMED_MODULES: dict[str, str] = {
    **{f"semdp.algos.fast.{m}": f"semdp.algos.kernels.{m}" for m in (
        "written", "ppo_actor_step", "stacked_critics", "gaussian_fisher", "mlp_grads",
        "sac_written")},
    **{f"semdp.algos.fast.{m}": f"semdp.algos.helpers.{m}" for m in (
        "critic_helper", "rollout_helper", "option_probe")},
    "semdp.algos.fast.helpers": "semdp.algos.helpers.modes",
    # SAC became one subpackage
    "semdp.algos.sac_learner": "semdp.algos.sac.learner",
    "semdp.algos.twin_q": "semdp.algos.sac.twin_q",
    "semdp.algos.learner_host": "semdp.algos.sac.learner_host",
    "semdp.algos.learner_process": "semdp.algos.sac.learner_process",
    "semdp.algos.replay_shared": "semdp.algos.sac.replay",
    "semdp.algos.n_step": "semdp.algos.sac.n_step",
}
#: The filter's ``lidar_bearing_bound`` as recorded before the aliasing bound -> today's value.
RECORDED_BOUNDS: dict[object, str] = {True: "bin", False: "none"}
#: Attributes added to a pickled class since: the value an object pickled before ran with.
ADDED_ATTRIBUTES: dict[str, dict[str, object]] = {
    "semdp.embedded.shield.SafetyShield": {"fallback": "escape", "kernel": "compiled",
                                           "_buttons": None, "gremlins": "orbit",
                                           "_plan": None, "_plan_seen": None,
                                           "_kept_for": 0},
    "semdp.embedded.wrapper.SafetyEmbeddedEnv": {"_buttons": None, "gremlins": "orbit"},
    "semdp.embedded.brake_kernel.ClearanceKernel": {"native": False},
}
#: On-policy algorithms' ``_target_``: a node without ``gradients`` ran autograd's derivatives.
ON_POLICY_TARGETS: frozenset[str] = frozenset(
    f"semdp.algos.{name}" for name in ("PPO", "PPOLag", "SPPPOLag", "TRPO", "TRPOLag", "CPO"))
SEMDP_TARGET = "semdp.embedded.wrapper.SafetyEmbeddedEnv"
SHIELD_TARGET = "semdp.embedded.shield.SafetyShield"


# ---------------------------------------------------------------- run configs
def _legacy_follower(name: str) -> DictConfig:
    """A follower saved by name (``point``, ``car_ppo_lag``, ...): the ``follower`` or
    ``ppo_lag_follower`` node of ``conf/robot/<robot>.yaml`` that holds it now."""
    robot, _, kind = name.partition("_")
    key = {"": "follower", "ppo_lag": "ppo_lag_follower"}.get(kind)
    if key is None:
        raise ValueError(f"unknown follower {name!r}: <robot> or <robot>_ppo_lag")
    return compose_node("robot", robot)[key]


def _wrapper_by_name(node: DictConfig) -> None:
    """A SEMDP wrapper's planner and follower saved by name -> their ``conf`` nodes."""
    planner = node.get("planner")
    if isinstance(planner, str):
        composed = OmegaConf.to_container(compose_node("planner", planner))
        node.planner = {**composed, **(node.get("planner_kwargs") or {})}  # type: ignore[dict-item]
    follower = node.get("follower")
    if follower == "auto":
        node.follower = None
    elif isinstance(follower, str):
        node.follower = _legacy_follower(follower)
    for key in ("planner_kwargs", "_recursive_"):
        node.pop(key, None)


def _planner_legacy() -> Any:
    """The planner's compatibility module, imported on first use: CasADi and the planner load
    only with a run or checkpoint that holds a planner."""
    from solvers.planner import legacy

    return legacy


def upgrade_node(node: Any) -> None:
    """:func:`upgrade_run_config` of one node and everything below it, in place."""
    if isinstance(node, DictConfig):
        target = node.get("_target_") if "_target_" in node else None
        if isinstance(target, str) and target in RENAMED_TARGETS:
            node._target_ = target = RENAMED_TARGETS[target]
        if target == SEMDP_TARGET:
            _wrapper_by_name(node)
        if (isinstance(target, str) and target.startswith("solvers.planner.")
                and target == _planner_legacy().PLANNER_TARGET
                and _planner_legacy().is_old_planner_node(node)):
            old = OmegaConf.to_container(node, resolve=False)
            for key in list(node):
                node.pop(key)
            node.merge_with(_planner_legacy().planner_node(old))  # type: ignore[arg-type]
        if target == SHIELD_TARGET and node.get("lidar_bearing_bound") in RECORDED_BOUNDS:
            node.lidar_bearing_bound = RECORDED_BOUNDS[node.lidar_bearing_bound]
        if target in (SEMDP_TARGET, SHIELD_TARGET) and "gremlins" not in node:
            node.gremlins = "orbit"
        if target in ON_POLICY_TARGETS and "gradients" not in node:
            node.gradients = "autograd"
        for key in node:
            if not (OmegaConf.is_missing(node, key) or OmegaConf.is_interpolation(node, key)):
                upgrade_node(node[key])
    elif isinstance(node, ListConfig):
        for item in node:
            upgrade_node(item)


def upgrade_run_config(cfg: DictConfig) -> DictConfig:
    """A saved run config in today's form, in place (see the module docstring); returned.

    Raises:
        ValueError: a planner or follower saved by a name that no ``conf`` option holds.
    """
    upgrade_node(cfg)
    return cfg


# ---------------------------------------------------------------- checkpoints
def _shield_state(state: dict[str, Any]) -> dict[str, Any]:
    bound = state.get("lidar_bearing_bound")
    if bound in RECORDED_BOUNDS:
        state["lidar_bearing_bound"] = RECORDED_BOUNDS[bound]  # type: ignore[index]
    if type(state.get("_plan_seen")) is tuple:  # a (statics, homes) pair: not where it was read
        state["_plan"], state["_plan_seen"] = None, None  # the next step plans afresh
    return state


@functools.cache
def _with_added(path: str, cls: type) -> type:
    added = ADDED_ATTRIBUTES[path]

    def upgrade(state: dict[str, Any]) -> dict[str, Any]:
        state = {**added, **state}
        return _shield_state(state) if path == SHIELD_TARGET else state

    return _planner_legacy().upgrading(cls, upgrade)


class Unpickler(pickle.Unpickler):
    """An unpickler that reads checkpoints of earlier versions (see the module docstring)."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in (("pickle", "loads"), ("_pickle", "loads")):
            return loads  # a blob pickled inside the checkpoint: read it the same way
        found = (_planner_legacy().find_class(module, name)
                 if module.startswith("solvers.planner") else None)
        if found is not None:
            return found
        module = RENAMED_MODULES.get(module, module)
        path = RENAMED_TARGETS.get(f"{module}.{name}", f"{module}.{name}")
        module, _, name = path.rpartition(".")
        cls = super().find_class(module, name)
        return _with_added(path, cls) if path in ADDED_ATTRIBUTES else cls


def loads(data: bytes) -> Any:
    """``pickle.loads`` through :class:`Unpickler`."""
    return Unpickler(io.BytesIO(data)).load()


def load(file: Any) -> Any:
    """``pickle.load`` through :class:`Unpickler` (with :class:`Unpickler`, what
    ``torch.load(..., pickle_module=semdp.legacy)`` needs)."""
    return Unpickler(file).load()

