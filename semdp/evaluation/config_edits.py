"""Apply ``semdp-eval``'s shorthands and overrides to a run's saved, resolved ``config.yaml``.

The saved config of a Safety-Embedded MDP run (loaded in today's form by
:func:`semdp.run_config.load_run_config`) holds its evaluation wrapper as ``env.eval_wrapper``
with the planner as a full ``conf/planner`` node (``_target_``, ``problem``, ``backend``,
``rescue_backend``) and the follower as a node of the robot's ``conf/robot/<robot>.yaml``
(docs/semdp.md). The shorthands edit that node:

- ``planner=<name>``: ``conf/planner/<name>.yaml`` composed with Hydra's compose API; the run's
  clearance is kept, and its ``rescue_backend`` too when the planner class is the same;
- ``clearance=<eps'>``: the planner's clearance (``problem.clearance``; ``clearance`` of a
  planner node saved without a ``problem`` node);
- ``lambda=fixed|adaptive``: ``backend.adaptive`` of an LM planner (thesis App. B.2.3);
- ``perception=lidar|lidar_refined|gt``: the wrapper's ``perception`` (the filter keeps its
  own).
"""

from __future__ import annotations

import copy
from typing import Any

from omegaconf import DictConfig, OmegaConf

from semdp.configs import compose_node
from semdp.evaluation.errors import EvalError
from semdp.evaluation.options import SHORTHANDS, EvalOptions

SEMDP_TARGET = "semdp.embedded.wrapper.SafetyEmbeddedEnv"
LM_SETTINGS_TARGET = "solvers.planner.LMSettings"
_ABSENT = object()


def is_semdp_wrapper(node: Any) -> bool:
    """Whether ``node`` is a ``SafetyEmbeddedEnv`` wrapper node."""
    return OmegaConf.is_dict(node) and str(node.get("_target_", "")) == SEMDP_TARGET


def _compose(group: str, name: str) -> DictConfig:
    try:
        return compose_node(group, name)
    except ValueError as exc:
        raise EvalError(str(exc)) from None


def evaluation_wrapper(cfg: DictConfig, what: str) -> DictConfig:
    """The SEMDP wrapper node the evaluation uses (a copy of ``wrapper`` when ``eval_wrapper``
    is null), for the shorthand ``what``.

    Raises:
        EvalError: the run has no Safety-Embedded MDP wrapper.
    """
    env = cfg.env
    if env.get("eval_wrapper") is None and is_semdp_wrapper(env.get("wrapper")):
        env.eval_wrapper = copy.deepcopy(env.wrapper)
    node = env.get("eval_wrapper")
    if not is_semdp_wrapper(node):
        run = f"{cfg.get('algo_name') or 'the algorithm'} on {cfg.get('env_name') or env.get('id')}"
        raise EvalError(f"{what}= applies to Safety-Embedded MDP runs; this run is {run} "
                        "(no SafetyEmbeddedEnv wrapper)")
    return node


def _planner(cfg: DictConfig, what: str) -> DictConfig:
    node = evaluation_wrapper(cfg, what).get("planner")
    if not OmegaConf.is_dict(node):
        raise EvalError(f"{what}=: env.eval_wrapper.planner is not a planner node: {node!r}")
    return node


def _holding_clearance(planner: DictConfig) -> DictConfig:
    """The node of a planner that holds its ``clearance`` (its ``problem`` node, if any)."""
    problem = planner.get("problem")
    return problem if OmegaConf.is_dict(problem) else planner


def replace_planner(cfg: DictConfig, name: str) -> None:
    """``planner=<name>``: a fresh ``conf/planner`` node, keeping the run's eps' and rescue."""
    wrapper = evaluation_wrapper(cfg, "planner")
    old = wrapper.get("planner")
    new = _compose("planner", name)
    if OmegaConf.is_dict(old):
        before, after = _holding_clearance(old), _holding_clearance(new)
        if "clearance" in before and "clearance" in after:
            after.clearance = before.clearance
        if old.get("_target_") == new.get("_target_") and "rescue_backend" in old:
            new.rescue_backend = old.rescue_backend
    wrapper.planner = new


def set_clearance(cfg: DictConfig, clearance: float) -> None:
    """``clearance=<eps'>`` on the evaluation planner."""
    node = _planner(cfg, "clearance")
    holder = _holding_clearance(node)
    if "clearance" not in holder:
        raise EvalError(f"the evaluation planner {node.get('_target_')} has no clearance")
    holder.clearance = float(clearance)


def set_lambda(cfg: DictConfig, mode: str) -> None:
    """``lambda=fixed|adaptive`` on an LM evaluation planner (a ``backend`` node of
    ``LMSettings``)."""
    node = _planner(cfg, "lambda")
    backend = node.get("backend")
    adaptive = mode == "adaptive"
    if OmegaConf.is_dict(backend) and str(backend.get("_target_", "")) == LM_SETTINGS_TARGET:
        backend.adaptive = adaptive
    else:
        kind = backend.get("_target_") if OmegaConf.is_dict(backend) else backend
        raise EvalError(f"lambda= needs the LM planner; the evaluation planner is "
                        f"{node.get('_target_')} with backend {kind!r}")


def apply_overrides(cfg: DictConfig, options: EvalOptions) -> None:
    """The plain ``key=value`` overrides, in place.

    Raises:
        EvalError: ``key=value`` naming a key the config does not have (``+key=`` adds one).
    """
    for item in options.overrides:
        if not item.add and OmegaConf.select(cfg, item.key, default=_ABSENT) is _ABSENT:
            raise EvalError(
                f"unknown key {item.key!r}: not in the run's config.yaml (+{item.key}=... adds "
                f"it; evaluation settings: {', '.join(SHORTHANDS)})")
        try:
            OmegaConf.update(cfg, item.key, item.value, merge=False, force_add=item.add)
        except Exception as exc:  # e.g. a key below a non-mapping value
            raise EvalError(f"cannot set {item.key}: {exc}".splitlines()[0]) from None


def edited_config(saved: DictConfig, options: EvalOptions) -> DictConfig:
    """A copy of ``saved`` with the shorthands, then the plain overrides, applied."""
    cfg = copy.deepcopy(saved)
    if options.planner is not None:
        replace_planner(cfg, options.planner)
    if options.clearance is not None:
        set_clearance(cfg, options.clearance)
    if options.lambda_ is not None:
        set_lambda(cfg, options.lambda_)
    if options.perception is not None:
        evaluation_wrapper(cfg, "perception").perception = options.perception
    apply_overrides(cfg, options)
    return cfg
