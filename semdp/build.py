"""From a composed training config to the objects: validate it, seed, build the envs and the
algorithm (docs/design.md, "From the command line to the objects"). Library code builds runs
through this module, never through the ``semdp-train`` app (:mod:`semdp.cli.train`).
"""

from __future__ import annotations

import math
from typing import Any

from hydra.utils import get_class, instantiate
from omegaconf import DictConfig, OmegaConf

from semdp.algos import speedups
from semdp.algos.base import Algorithm
from semdp.algos.on_policy import OnPolicyAlgorithm
from semdp.common.seeding import seed_everything
from semdp.envs import make_vec_env


class ConfigError(ValueError):
    """A bad configuration value, found before anything is built (the message names the key)."""


def _non_finite(node: object, prefix: str = "") -> str | None:
    """The dotted key of the first NaN or infinity in a resolved config tree, else None."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        is_bad = isinstance(node, float) and not math.isfinite(node)
        return prefix[:-1] if is_bad else None
    for key, value in items:
        found = _non_finite(value, f"{prefix}{key}.")
        if found is not None:
            return found
    return None


def validate_config(cfg: DictConfig) -> None:
    """Fail fast, naming the offending key, before anything is built."""

    def number(key: str) -> float:
        value = OmegaConf.select(cfg, key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{key} must be a number, got {value!r}")
        return float(value)

    def integer(key: str, minimum: int) -> None:
        """A whole number (``1e6`` counts) of at least ``minimum``."""
        value = number(key)
        if not math.isfinite(value) or value != int(value) or value < minimum:
            raise ConfigError(f"{key} must be an integer >= {minimum}, got "
                              f"{OmegaConf.select(cfg, key)!r}")

    if cfg.get("algo") is None or "_target_" not in cfg.algo:
        raise ConfigError("algo must be chosen from conf/algo (e.g. algo=ppo_lag); got none")
    cost_limit = number("cost_limit")
    if not math.isfinite(cost_limit) or cost_limit < 0:
        raise ConfigError(f"cost_limit must be a finite number >= 0, got {cost_limit}")
    for key in ("total_steps", "algo.steps_per_epoch", "torch_threads", "env.num_envs"):
        integer(key, 1)
    for key in ("eval_every", "eval_episodes", "final_eval_episodes", "checkpoint_every", "seed"):
        integer(key, 0)
    if int(cfg.eval_every) > 0 and int(cfg.eval_episodes) < 1:
        raise ConfigError(f"eval_episodes must be >= 1 while eval_every > 0 (eval_every=0 turns "
                          f"the periodic evaluation off), got {cfg.eval_episodes}")
    if "eval_workers" in cfg:  # absent in older runs' configs
        integer("eval_workers", 1)
    if not cfg.env.get("id"):
        raise ConfigError("env.id must name a gymnasium id, got none")
    sizes = cfg.algo.get("hidden_sizes")
    if sizes is not None and (
        not OmegaConf.is_list(sizes) or len(sizes) == 0
        or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes)):
        shown = OmegaConf.to_container(sizes) if OmegaConf.is_list(sizes) else sizes
        raise ConfigError(f"algo.hidden_sizes must be a non-empty list of layer widths >= 1, "
                          f"e.g. [64,64], got {shown!r}")
    found = _non_finite(OmegaConf.to_container(cfg, resolve=True))
    if found is not None:
        raise ConfigError(f"{found} must be a finite number, got {OmegaConf.select(cfg, found)}")


def algorithm_node(algo: DictConfig) -> tuple[dict[str, Any], dict[str, Any]]:
    """``algo`` resolved, and the seams built from its speed-up keys: an on-policy algorithm's
    ``gradients`` / ``vectorization`` / ``parallel_critics`` become its ``kernel`` and
    ``runners`` (:mod:`semdp.algos.speedups`); other algorithms' nodes pass unchanged."""
    node = OmegaConf.to_container(algo, resolve=True)
    assert isinstance(node, dict)
    if not issubclass(get_class(str(node["_target_"])), OnPolicyAlgorithm):
        return node, {}
    keys = {key: node.pop(key) for key in speedups.KEYS if key in node}
    return node, speedups.on_policy_seams(**keys)


def build_algorithm(cfg: DictConfig) -> Algorithm:
    """Seed, make the training and evaluation vector envs, and instantiate ``cfg.algo`` with
    its seams (:func:`algorithm_node`)."""
    seed_everything(int(cfg.seed))
    node, seams = algorithm_node(cfg.algo)
    envs = make_vec_env(cfg.env, seed=int(cfg.seed))
    eval_n = max(1, min(int(cfg.env.num_envs), max(int(cfg.eval_episodes), 1)))
    eval_envs = make_vec_env(cfg.env, seed=int(cfg.seed) + 1, num_envs=eval_n, evaluation=True)
    return instantiate(node, envs=envs, eval_envs=eval_envs, seed=int(cfg.seed), **seams,
                       _convert_="all")
