"""``semdp-bench train``: end-to-end training throughput (env steps/s) per algorithm, and its split.

    semdp-bench train                                    # PPO-Lag on the test CMDP
    semdp-bench train env=point_goal1 algos=ppo_lag,cpo,sac epochs=3 steps_per_epoch=10000
    semdp-bench train env=point_goal1 algos=ppo_lag vectorization=sync parallel_critics=false

Each algorithm is built exactly as ``semdp-train`` builds it (same configs, same vector env), runs
``epochs`` epochs after one warm-up epoch, and the table reports env steps per second of training
(rollout + update, no evaluation) -- the ``fps`` column of ``progress.csv`` -- and where the time
went (:class:`semdp.common.phase_timer.PhaseTimer`): simulation (stepping the envs, or waiting for
the helper that steps them), policy (actor and critic forward passes while acting), storage (buffer
writes, bookkeeping, GAE) and update (actor and critic optimisation), in percent of the wall time;
``helper sim`` is the time the env helper spent stepping (``vectorization=async``), which overlaps
the rest. ``vectorization`` and ``parallel_critics`` override the on-policy algorithms' settings
(empty: their default, ``auto``, which probes both ways in the first two epochs; the table shows the
way used last). Results are also written to ``outputs/bench/train_<env>.csv``. Machine load changes
the figures: report it with them.
"""

from __future__ import annotations

import csv
import os
import platform
import time
from pathlib import Path
from typing import Any

import torch
from hydra import compose, initialize_config_dir

from semdp.benchmarks.arguments import as_int, as_items, parse_args
from semdp.build import build_algorithm
from semdp.paths import CONF_DIR, REPO_ROOT

DEFAULTS = {"env": "speed_limit", "algos": "ppo_lag", "epochs": "3", "steps_per_epoch": "10000",
            "num_envs": "", "torch_threads": "1", "out": "", "vectorization": "",
            "parallel_critics": ""}
SPLIT = ("simulation", "policy", "storage", "update")


def measure(
    env: str,
    algo: str,
    epochs: int,
    steps_per_epoch: int,
    num_envs: str,
    vectorization: str = "",
    parallel_critics: str = "",
) -> dict[str, Any]:
    """Build one algorithm as the trainer does and time ``epochs`` epochs after a warm-up."""
    overrides = [f"algo={algo}", f"env={env}", f"budget.steps_per_epoch={steps_per_epoch}"]
    if num_envs:
        overrides.append(f"env.num_envs={num_envs}")
    if algo == "sac":  # measure learning throughput, not the random warm-up
        overrides.append(f"algo.learning_starts={min(1000, steps_per_epoch)}")
    else:
        if vectorization:
            overrides.append(f"algo.vectorization={vectorization}")
        if parallel_critics:
            overrides.append(f"algo.parallel_critics={parallel_critics}")
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=overrides)
    model = build_algorithm(cfg)
    try:
        model.total_epochs = epochs + 1
        model.train_epoch()  # warm-up (SAC: fills the buffer past learning_starts)
        before = model.timer.snapshot()
        start, steps0 = time.perf_counter(), model.env_steps
        for _ in range(epochs):
            model.train_epoch()
        elapsed = time.perf_counter() - start
    finally:
        model.close_helpers()
    spent = {k: v - before[k] for k, v in model.timer.snapshot().items()}
    steps = model.env_steps - steps0
    row: dict[str, Any] = {
        "env": env, "algo": algo, "num_envs": model.num_envs,
        "vectorization": "async" if getattr(model, "envs_in_helper", False) else "sync",
        "parallel_critics": bool(getattr(model, "critics_in_helper", False)),
        "env_steps": steps, "seconds": round(elapsed, 3), "fps": round(steps / elapsed, 1),
    }
    for phase in SPLIT:
        row[f"{phase}_pct"] = round(100 * spent[phase] / elapsed, 1)
    row["other_pct"] = round(100 - sum(row[f"{p}_pct"] for p in SPLIT), 1)
    row["helper_sim_pct"] = round(100 * spent["simulation_worker"] / elapsed, 1)
    return row


def main(argv: list[str]) -> None:
    """Print the throughput table and write the CSV."""
    args = parse_args("train", argv, DEFAULTS)
    torch.set_num_threads(as_int(args, "torch_threads", minimum=1))
    epochs = as_int(args, "epochs", minimum=1)
    steps_per_epoch = as_int(args, "steps_per_epoch", minimum=1)
    rows = [
        measure(args["env"], algo, epochs, steps_per_epoch, args["num_envs"],
                args["vectorization"], args["parallel_critics"])
        for algo in as_items(args, "algos")
    ]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"training throughput on {platform.node()} ({platform.processor() or 'cpu'}), "
          f"torch threads {args['torch_threads']}, load average {load:.2f}")
    print(f"{'algo':<12} {'env':<14} {'envs':>5} {'vec':>5} {'crit':>5} {'steps':>8} {'s':>7} "
          f"{'steps/s':>8} {'sim%':>5} {'pol%':>5} {'sto%':>5} {'upd%':>5} {'oth%':>5} "
          f"{'helper sim%':>11}")
    for r in rows:
        print(f"{r['algo']:<12} {r['env']:<14} {r['num_envs']:>5} {r['vectorization']:>5} "
              f"{'yes' if r['parallel_critics'] else 'no':>5} {r['env_steps']:>8} "
              f"{r['seconds']:>7.2f} {r['fps']:>8.0f} {r['simulation_pct']:>5.1f} "
              f"{r['policy_pct']:>5.1f} {r['storage_pct']:>5.1f} {r['update_pct']:>5.1f} "
              f"{r['other_pct']:>5.1f} {r['helper_sim_pct']:>11.1f}")
    out = Path(args["out"]) if args["out"] else REPO_ROOT / "outputs" / "bench" / \
        f"train_{args['env']}.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {out}")
