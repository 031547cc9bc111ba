"""The eps' trade-off of a trained SEMDP policy (thesis App. B.1.1, Fig. B.1).

At test time the planner's clearance eps' (Eq. 3.2; ``clearance`` of ``conf/planner/*.yaml``)
sets how far plans keep from the obstacles: a smaller eps' gives a less conservative agent.
:func:`tradeoff_points` evaluates one policy at several eps' and returns the list that
``semdp-report`` plots as the Fig. B.1 scatter (``metrics.json`` key ``tradeoff``).

    # as the post-training hook of the semdp_tradeoff preset (conf/experiment/semdp_tradeoff.yaml)
    # or on any finished SEMDP run directory:
    python -m semdp.experiments.tradeoff <run dir> --clearances 0.1,0.25,0.5 --episodes 10
"""

from __future__ import annotations

import argparse
import copy
import json
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from semdp.algos.base import Algorithm
from semdp.common.logger import write_metrics
from semdp.evaluation.loading import env_config, load_trained
from semdp.evaluation.variant import chain_post_train, evaluate_on

logger = logging.getLogger(__name__)

#: Default eps' values (m); 0.5 is the thesis' (and conf/planner's) setting.
DEFAULT_CLEARANCES: tuple[float, ...] = (0.1, 0.25, 0.5, 0.75)


def is_semdp_env(env_cfg: dict[str, Any]) -> bool:
    """Whether an env config wraps its env in a planner (a ``semdp_*`` env config)."""
    node = env_cfg.get("eval_wrapper") or env_cfg.get("wrapper")
    return isinstance(node, dict) and isinstance(node.get("planner"), dict)


def with_clearance(env_cfg: dict[str, Any], clearance: float) -> dict[str, Any]:
    """A copy of a SEMDP env config whose *evaluation* planner uses ``clearance`` as eps'.

    Raises:
        ValueError: the env has no SEMDP ``eval_wrapper``/``wrapper`` with a planner node, or
            ``clearance`` is negative.
    """
    if not clearance >= 0:
        raise ValueError(f"clearance (eps') must be >= 0, got {clearance}")
    out = copy.deepcopy(env_cfg)
    key = "eval_wrapper" if out.get("eval_wrapper") else "wrapper"
    node = out.get(key)
    if not isinstance(node, dict) or not isinstance(node.get("planner"), dict):
        raise ValueError(
            f"env {out.get('id')!r} is not a Safety-Embedded MDP env (no planner in env.{key}); "
            "the eps' trade-off needs a semdp_* env config"
        )
    planner = node["planner"]
    holder = planner["problem"] if isinstance(planner.get("problem"), dict) else planner
    holder["clearance"] = float(clearance)
    return out


def tradeoff_points(
    algo: Algorithm, cfg: DictConfig, clearances: Sequence[float], episodes: int, seed: int = 0
) -> list[dict[str, float]]:
    """Mean-action evaluation at each eps'; the ``tradeoff`` entries of ``metrics.json``."""
    if not clearances:
        raise ValueError("clearances must list at least one eps' value")
    base = env_config(cfg)
    n_envs = max(1, min(int(base.get("num_envs", 1)), episodes))
    points = []
    for clearance in clearances:
        result = evaluate_on(algo, with_clearance(base, float(clearance)), episodes,
                             seed=10_000 + seed, num_envs=n_envs)
        logger.info("eps'=%.3g: return %.3f cost %.3f over %d episodes", clearance,
                    result["return_mean"], result["cost_mean"], result["episodes"])
        points.append({"clearance": float(clearance), "return_mean": result["return_mean"],
                       "cost_mean": result["cost_mean"], "episodes": result["episodes"]})
    return points


def after_training(
    *, algo: Algorithm, cfg: DictConfig, run_dir: Path, metrics: dict[str, Any],
    clearances: Sequence[float] = DEFAULT_CLEARANCES, episodes: int = 10,
) -> dict[str, Any]:
    """``post_train`` hook: the env's own hook first, then ``metrics["tradeoff"]``.

    Runs that are not in a Safety-Embedded MDP (the baselines of the same sweep) are left as
    they are: Fig. B.1 shows them as single points from their final evaluation.
    """
    metrics = chain_post_train(cfg.env.get("post_train"), algo=algo, cfg=cfg, run_dir=run_dir,
                               metrics=metrics)
    if not is_semdp_env(env_config(cfg)):
        return metrics
    metrics["tradeoff"] = tradeoff_points(algo, cfg, list(clearances), int(episodes),
                                          seed=int(cfg.seed))
    return metrics


def main(argv: list[str] | None = None) -> None:
    """CLI: add ``tradeoff`` to the ``metrics.json`` of finished SEMDP run directories."""
    parser = argparse.ArgumentParser(prog="python -m semdp.experiments.tradeoff",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dirs", nargs="+", type=Path)
    parser.add_argument("--clearances", default=",".join(map(str, DEFAULT_CLEARANCES)),
                        help="comma-separated eps' values in metres")
    parser.add_argument("--episodes", type=int, default=10)
    args = parser.parse_args(argv)
    clearances = [float(v) for v in args.clearances.split(",") if v.strip()]
    for run_dir in args.run_dirs:
        algo, cfg = load_trained(run_dir)
        metrics_path = run_dir / "metrics.json"
        metrics = json.loads(metrics_path.read_text()) if metrics_path.is_file() else {}
        metrics["tradeoff"] = tradeoff_points(algo, cfg, clearances, args.episodes,
                                              seed=int(cfg.seed))
        write_metrics(metrics_path, metrics)
        for p in metrics["tradeoff"]:
            print(f"{run_dir}: eps'={p['clearance']:g} return {p['return_mean']:.3f} "
                  f"cost {p['cost_mean']:.3f}")


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    main()
