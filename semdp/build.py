"""From a composed training config to the objects: validate it, seed, build the envs and the
algorithm (docs/design.md, "From the command line to the objects"). Library code builds runs
through this module, never through the ``semdp-train`` app (:mod:`semdp.cli.train`).
"""

from __future__ import annotations

import math

from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from semdp.algos.base import Algorithm
from semdp.common.seeding import seed_everything
from semdp.envs import make_vec_env


class ConfigError(ValueError):
    """A bad configuration value, found before anything is built (the message names the key)."""


def validate_config(cfg: DictConfig) -> None:
    """Fail fast, naming the offending key, before anything is built."""

    def number(key: str) -> float:
        value = OmegaConf.select(cfg, key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{key} must be a number, got {value!r}")
        return float(value)

    if cfg.get("algo") is None or "_target_" not in cfg.algo:
        raise ConfigError("algo must be chosen from conf/algo (e.g. algo=ppo_lag); got none")
    cost_limit = number("cost_limit")
    if not math.isfinite(cost_limit) or cost_limit < 0:
        raise ConfigError(f"cost_limit must be a finite number >= 0, got {cost_limit}")
    for key in ("total_steps", "algo.steps_per_epoch"):
        if number(key) <= 0:
            raise ConfigError(f"{key} must be > 0, got {OmegaConf.select(cfg, key)}")
    for key in ("eval_every", "eval_episodes", "final_eval_episodes", "checkpoint_every"):
        if number(key) < 0:
            raise ConfigError(f"{key} must be >= 0, got {OmegaConf.select(cfg, key)}")
    if number("seed") < 0:
        raise ConfigError(f"seed must be >= 0, got {cfg.seed}")
    if number("torch_threads") < 1:
        raise ConfigError(f"torch_threads must be >= 1, got {cfg.torch_threads}")
    if "eval_workers" in cfg and number("eval_workers") < 1:  # absent in older runs' configs
        raise ConfigError(f"eval_workers must be >= 1, got {cfg.eval_workers}")
    if number("env.num_envs") < 1:
        raise ConfigError(f"env.num_envs must be >= 1, got {cfg.env.num_envs}")
    if not cfg.env.get("id"):
        raise ConfigError("env.id must name a gymnasium id, got none")


def build_algorithm(cfg: DictConfig) -> Algorithm:
    """Seed, make the training and evaluation vector envs, and instantiate ``cfg.algo``."""
    seed_everything(int(cfg.seed))
    envs = make_vec_env(cfg.env, seed=int(cfg.seed))
    eval_n = max(1, min(int(cfg.env.num_envs), max(int(cfg.eval_episodes), 1)))
    eval_envs = make_vec_env(cfg.env, seed=int(cfg.seed) + 1, num_envs=eval_n, evaluation=True)
    return instantiate(cfg.algo, envs=envs, eval_envs=eval_envs, seed=int(cfg.seed),
                       _convert_="all")
