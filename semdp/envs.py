"""Environment factory: ``gymnasium.make`` + optional per-env wrapper + vectorisation.

The env node of a config (``conf/env``) is the argument of :func:`make_vec_env`; see
``docs/design.md`` for the data flow config -> env -> wrapper -> planner -> follower.

Importing this module imports :mod:`sims`, which registers the ``sims/...`` ids (pymunk Safety Gym
replica, driving tasks) and the test CMDP ``semdp/SpeedLimit-v0`` (:mod:`sims.testbed`).

Vector envs use gymnasium's ``SyncVectorEnv`` with ``AutoresetMode.SAME_STEP``: when a sub-env's
episode ends, the returned observation is already the first one of the next episode and the
true final observation / info are in ``infos["final_obs"]`` / ``infos["final_info"]``.
:func:`semdp.common.vector_stepping.merged_step_result` resolves both for the algorithms.
"""

from __future__ import annotations

import functools
import importlib
import logging
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
from hydra.utils import get_class, instantiate
from omegaconf import OmegaConf

logger = logging.getLogger(__name__)

try:  # the pymunk envs are optional at import time so the trainer works while they are built
    importlib.import_module("sims")
except ImportError as exc:  # pragma: no cover - depends on the checkout
    logger.warning("could not import sims (%s); sims/... ids are unavailable", exc)


class ZeroCost(gym.Wrapper):
    """Adds ``info["cost"] = 0.0`` to envs that have no cost (e.g. ``Pendulum-v1``)."""

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step and add a zero cost when none is reported."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        info.setdefault("cost", 0.0)
        return obs, reward, terminated, truncated, info


class RequireCost(gym.Wrapper):
    """Fails loudly on the first step that lacks ``info["cost"]``."""

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step and check for the cost."""
        out = self.env.step(action)
        if "cost" not in out[4]:
            raise KeyError(
                f"{self.env.spec.id if self.env.spec else self.env} reports no info['cost']; "
                "set env.add_zero_cost=true for an unconstrained task"
            )
        return out


def make_env(
    env_id: str,
    kwargs: Mapping[str, Any] | None = None,
    wrapper: Callable[[gym.Env], gym.Env] | Mapping[str, Any] | None = None,
    add_zero_cost: bool = False,
) -> gym.Env:
    """One environment: ``gymnasium.make(env_id, **kwargs)``, then ``wrapper`` and the cost check.

    ``wrapper`` is a callable or a Hydra node (``_target_`` + ``_partial_: true``) that is
    instantiated here, once per environment, so that the objects it holds (a planner with its
    warm start, a follower) belong to this environment alone. A module-level function so that
    ``functools.partial(make_env, ...)`` pickles (checkpoints pickle the vector env).
    """
    if env_id not in gym.registry:
        known = sorted(k for k in gym.registry if k.startswith(("sims/", "semdp/")))
        raise ValueError(f"unknown env id {env_id!r}; registered project ids: {known}")
    env = apply_wrapper(gym.make(env_id, **dict(kwargs or {})), wrapper)
    return ZeroCost(env) if add_zero_cost else RequireCost(env)


def apply_wrapper(
    env: gym.Env, wrapper: Callable[[gym.Env], gym.Env] | Mapping[str, Any] | None
) -> gym.Env:
    """``env`` wrapped by a callable, by a freshly instantiated ``_partial_`` node, or as is."""
    if wrapper is None:
        return env
    if isinstance(wrapper, Mapping) or OmegaConf.is_config(wrapper):
        wrapper = instantiate(wrapper)
        if not callable(wrapper):
            raise ValueError(f"env.wrapper must instantiate to a callable, got {type(wrapper)}")
    return wrapper(env)


def plain_wrapper(wrapper: Any) -> Callable[[gym.Env], gym.Env] | dict[str, Any] | None:
    """A callable as it is; a config node as a plain, resolved dict (the factory is pickled)."""
    if wrapper is None or callable(wrapper):
        return wrapper
    if OmegaConf.is_config(wrapper):
        wrapper = OmegaConf.to_container(wrapper, resolve=True)
    if not isinstance(wrapper, Mapping) or "_target_" not in wrapper:
        raise ValueError(f"env.wrapper must be null, a callable or a _target_ node: {wrapper!r}")
    return dict(wrapper)


def make_vec_env(
    env_cfg: Mapping[str, Any], seed: int, num_envs: int | None = None, evaluation: bool = False
) -> gym.vector.SyncVectorEnv:
    """A seeded ``SyncVectorEnv`` from an env config node.

    Args:
        env_cfg: mapping with ``id``, ``num_envs``, ``kwargs`` (dict), optional ``wrapper`` (a
            callable, or a Hydra node with ``_target_`` and ``_partial_: true`` applied to each
            sub-env before vectorisation), optional ``add_zero_cost`` and optional ``vector``
            (dotted path of a vector env class built like ``SyncVectorEnv``; default
            ``SyncVectorEnv``).
        seed: seeds the action spaces; the algorithm seeds ``reset``.
        num_envs: overrides ``env_cfg["num_envs"]``.
        evaluation: build the evaluation env: uses ``env_cfg["eval_wrapper"]`` when it is set
            (e.g. the SEMDP wrapper with adaptive lambda / exact IPOPT at test time), else
            ``wrapper``.
    """
    n = int(num_envs if num_envs is not None else env_cfg.get("num_envs", 1))
    if n < 1:
        raise ValueError(f"env.num_envs must be >= 1, got {n}")
    kwargs = dict(env_cfg.get("kwargs") or {})
    wrapper = env_cfg.get("wrapper")
    if evaluation and env_cfg.get("eval_wrapper") is not None:
        wrapper = env_cfg.get("eval_wrapper")
    factory = functools.partial(
        make_env,
        env_cfg["id"],
        kwargs,
        plain_wrapper(wrapper),
        bool(env_cfg.get("add_zero_cost", False)),
    )
    # Optional ``vector``: a class built like SyncVectorEnv (e.g. the SEMDP lockstep one).
    vector_cls = get_class(env_cfg["vector"]) if env_cfg.get("vector") else gym.vector.SyncVectorEnv
    envs = vector_cls([factory] * n, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    envs.action_space.seed(seed)
    for i, sub in enumerate(envs.envs):
        sub.action_space.seed(seed + i)
    return envs
