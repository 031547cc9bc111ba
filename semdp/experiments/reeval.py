"""Evaluation-time variants of a trained run (cheap stand-ins for ablations, SPEC §4.2).

"Ours w/o Lag" (Table B.1) differs from Ours only at test time (fixed lambda in the evaluation
planner), and the perception of the *planner* can be switched to ground truth at test time
("Ours w/ gt" evaluated on a policy trained with LiDAR perception). This re-evaluates a trained
run with config overrides and writes a new run directory (metrics.json with its own label,
a copy of progress.csv and the modified config.yaml) that ``semdp-report`` reads beside the
others. Overrides apply to the *resolved* saved config, so name the evaluation wrapper's keys:

    python -m semdp.experiments.reeval <run dir> <new run dir> --label "Ours w/o Lag" \
        env.eval_wrapper.planner=lm
    python -m semdp.experiments.reeval <run dir> <new run dir> --label "Ours w/ gt (eval)" \
        env.eval_wrapper.perception=gt
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from semdp.algos.base import CHECKPOINT_NAME
from semdp.common.logger import write_metrics


def reevaluate(run_dir: Path, out_dir: Path, label: str, overrides: list[str],
               episodes: int = 50) -> dict[str, Any]:
    """Evaluate ``run_dir``'s final policy under ``overrides``; write ``out_dir``.

    Raises:
        ValueError: ``run_dir`` is not a finished run, ``out_dir`` exists, or an override is
            not ``key=value`` naming an existing key.
    """
    from semdp.train import build_algorithm

    run_dir, out_dir = Path(run_dir), Path(out_dir)
    ckpt = run_dir / "checkpoints" / CHECKPOINT_NAME
    if not ckpt.is_file() or not (run_dir / "config.yaml").is_file():
        raise ValueError(f"{run_dir} is not a finished run dir (needs config.yaml and {ckpt})")
    if out_dir.exists():
        raise ValueError(f"{out_dir} exists; choose a new directory")
    cfg = OmegaConf.load(run_dir / "config.yaml")
    for item in overrides:
        key, sep, _ = item.partition("=")
        if not sep or OmegaConf.select(cfg, key, default=None) is None:
            raise ValueError(f"override {item!r} must be key=value with an existing key")
    cfg = OmegaConf.merge(cfg, OmegaConf.from_dotlist(overrides))
    start = time.perf_counter()
    algo = build_algorithm(cfg)
    algo.load_checkpoint(ckpt)
    result = algo.evaluate(episodes)
    source = json.loads((run_dir / "metrics.json").read_text())
    out_dir.mkdir(parents=True)
    OmegaConf.save(cfg, out_dir / "config.yaml")
    if (run_dir / "progress.csv").is_file():
        shutil.copy(run_dir / "progress.csv", out_dir / "progress.csv")
    metrics = {
        "status": "completed", "error": None, "algo": label, "env": source.get("env"),
        "seed": source.get("seed"), "label": label, "env_steps": source.get("env_steps"),
        "wall_time_s": time.perf_counter() - start, "eval": result,
        "reevaluation_of": str(run_dir), "overrides": overrides,
    }
    write_metrics(out_dir / "metrics.json", metrics)
    return metrics


def main(argv: list[str] | None = None) -> None:
    """CLI entry point."""
    parser = argparse.ArgumentParser(prog="python -m semdp.experiments.reeval",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("overrides", nargs="*", help="key=value on the saved config")
    parser.add_argument("--label", required=True)
    parser.add_argument("--episodes", type=int, default=50)
    args = parser.parse_intermixed_args(argv)
    metrics = reevaluate(args.run_dir, args.out_dir, args.label, args.overrides, args.episodes)
    ev = metrics["eval"]
    print(f"{args.out_dir}: {args.label}: return {ev['return_mean']:.3f} cost "
          f"{ev['cost_mean']:.3f} over {ev['episodes']} episodes")


if __name__ == "__main__":
    main()
