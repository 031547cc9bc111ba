"""Simulated stand-in for the real-robot transfer experiment (thesis §3.6.4, Table 3.2).

The variant itself (sizes, robot shape, observation noise, short episodes, fixed layouts) is
:mod:`semdp.evaluation.transfer_variant`; this module trains with it as a ``post_train`` hook
and tabulates the results.

    python -m semdp.experiments.transfer eval <run dir> [<run dir> ...]   # adds metrics "transfer"
    python -m semdp.experiments.transfer table <sweep dir>                # transfer_table.md
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from semdp.algos.base import Algorithm
from semdp.common.logger import write_metrics
from semdp.evaluation.loading import env_config, load_trained
from semdp.evaluation.transfer_variant import (
    DEFAULT_SIZES,
    LAYOUT_SEED,
    transfer_env_config,
)
from semdp.evaluation.variant import chain_post_train, evaluate_on

logger = logging.getLogger(__name__)

def evaluate_transfer(
    algo: Algorithm, cfg: DictConfig, sizes: Mapping[str, float] | None = None,
    noise_std: float = 0.05, episode_steps: int = 600, layouts: int = 10,
) -> dict[str, Any]:
    """Mean-action evaluation on ``layouts`` fixed layouts of the perturbed Push variant."""
    if layouts < 1:
        raise ValueError(f"layouts must be >= 1, got {layouts}")
    env_cfg = transfer_env_config(env_config(cfg), dict(sizes or DEFAULT_SIZES), noise_std,
                                  episode_steps)
    result = evaluate_on(algo, env_cfg, layouts, seed=LAYOUT_SEED, num_envs=layouts)
    result.update(simulated=True, layouts=layouts, sizes=dict(sizes or DEFAULT_SIZES),
                  noise_std=float(noise_std), episode_steps=int(episode_steps))
    return result


def after_training(
    *, algo: Algorithm, cfg: DictConfig, run_dir: Path, metrics: dict[str, Any],
    sizes: Mapping[str, float] | None = None, noise_std: float = 0.05,
    episode_steps: int = 600, layouts: int = 10, replace_eval: bool = True,
) -> dict[str, Any]:
    """``post_train`` hook: the env's own hook, then ``metrics["transfer"]``.

    With ``replace_eval`` the transfer result becomes ``metrics["eval"]`` (the simulation
    evaluation moves to ``metrics["eval_train_env"]``), so ``semdp-report`` tabulates it.
    """
    metrics = chain_post_train(cfg.env.get("post_train"), algo=algo, cfg=cfg, run_dir=run_dir,
                               metrics=metrics)
    result = evaluate_transfer(algo, cfg, sizes, noise_std, episode_steps, layouts)
    metrics["transfer"] = result
    if replace_eval:
        metrics["eval_train_env"] = metrics.get("eval")
        metrics["eval"] = {k: result[k] for k in ("episodes", "return_mean", "return_std",
                                                  "cost_mean", "cost_std", "success_rate")}
    return metrics


def transfer_table(sweep_dir: Path) -> str:
    """Markdown Table 3.2 stand-in: per method and env, successes / layouts, reward, cost."""
    rows: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for path in sorted(Path(sweep_dir).rglob("metrics.json")):
        metrics = json.loads(path.read_text())
        if not metrics.get("transfer"):
            continue
        key = (str(metrics.get("env")), str(metrics.get("label") or metrics.get("algo")))
        rows.setdefault(key, []).append(metrics["transfer"])
    lines = ["**Simulated transfer** (perturbed sims Push variant, not a real robot; thesis "
             "Table 3.2 stand-in). Mean over seeds of each seed's result on the same fixed "
             "layouts.", "", "| env | method | seeds | succ rate | reward | cost |",
             "|---|---|---|---|---|---|"]
    for (env, method), results in sorted(rows.items()):
        succ = [r["success_rate"] for r in results if r.get("success_rate") is not None]
        n_layouts = int(results[0].get("layouts", results[0].get("episodes", 0)))
        rate = (f"{np.mean(succ) * n_layouts:.1f}/{n_layouts}" if succ else "–")
        lines.append(f"| {env} | {method} | {len(results)} | {rate} | "
                     f"{np.mean([r['return_mean'] for r in results]):.2f} | "
                     f"{np.mean([r['cost_mean'] for r in results]):.2f} |")
    if not rows:
        lines.append("| (no run with a transfer evaluation) | | | | | |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    """CLI: ``eval <run dirs>`` adds ``transfer`` to metrics.json; ``table <sweep dir>``."""
    parser = argparse.ArgumentParser(prog="python -m semdp.experiments.transfer",
                                     description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    ev = sub.add_parser("eval", help="evaluate finished runs on the perturbed variant")
    ev.add_argument("run_dirs", nargs="+", type=Path)
    ev.add_argument("--noise-std", type=float, default=0.05)
    ev.add_argument("--episode-steps", type=int, default=600)
    ev.add_argument("--layouts", type=int, default=10)
    tb = sub.add_parser("table", help="write <sweep dir>/report/transfer_table.md")
    tb.add_argument("sweep_dir", type=Path)
    args = parser.parse_args(argv)
    if args.command == "table":
        out = args.sweep_dir / "report" / "transfer_table.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(transfer_table(args.sweep_dir))
        print(out.read_text(), end="")
        print(f"wrote {out}")
        return
    for run_dir in args.run_dirs:
        algo, cfg = load_trained(run_dir)
        result = evaluate_transfer(algo, cfg, None, args.noise_std, args.episode_steps,
                                   args.layouts)
        metrics_path = run_dir / "metrics.json"
        metrics = json.loads(metrics_path.read_text()) if metrics_path.is_file() else {}
        metrics["transfer"] = result
        write_metrics(metrics_path, metrics)
        print(f"{run_dir}: success {result['success_rate']} return {result['return_mean']:.3f} "
              f"cost {result['cost_mean']:.3f} over {result['episodes']} layouts (simulated)")


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    main()
