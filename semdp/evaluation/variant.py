"""Evaluate a trained run on a modified evaluation env (docs/experiments.md, "How the presets
are built").

Both the eps' trade-off (Fig. B.1) and the transfer stand-in (Table 3.2) re-evaluate a policy
with the mean action on envs that differ from the training ones. :func:`evaluate_on` swaps a
freshly built evaluation vector env into the algorithm for one :meth:`Algorithm.evaluate` call.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from semdp.algos.base import Algorithm
from semdp.envs import make_vec_env

logger = logging.getLogger(__name__)


def evaluate_on(
    algo: Algorithm, env_cfg: Mapping[str, Any], episodes: int, seed: int, num_envs: int
) -> dict[str, Any]:
    """Mean-action evaluation of ``algo`` on envs built from ``env_cfg`` (evaluation variant).

    The algorithm's own evaluation envs are restored afterwards. With ``num_envs == episodes``
    every sub-env plays exactly one episode from ``reset(seed=seed + i)``: a fixed set of layouts.
    """
    if episodes < 1 or num_envs < 1:
        raise ValueError(f"episodes and num_envs must be >= 1, got {episodes}, {num_envs}")
    envs = make_vec_env(env_cfg, seed=seed, num_envs=num_envs, evaluation=True)
    saved = algo.eval_envs
    algo.eval_envs = envs
    try:
        return algo.evaluate(episodes, seed=seed)
    finally:
        algo.eval_envs = saved
        envs.close()


def chain_post_train(hook_cfg: Any, **kwargs: Any) -> dict[str, Any]:
    """Call the env config's own ``post_train`` hook (e.g. the SEMDP artefacts), if any."""
    from hydra.utils import instantiate

    metrics = kwargs["metrics"]
    if hook_cfg:
        metrics = instantiate(hook_cfg)(**kwargs)
    return metrics
