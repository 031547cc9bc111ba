"""``semdp-bench train``: end-to-end training throughput (env steps/s) per algorithm (SPEC §6).

    semdp-bench train                                    # PPO-Lag on the test CMDP
    semdp-bench train env=point_goal1 algos=ppo_lag,cpo,sac epochs=3 steps_per_epoch=10000

Each algorithm is built exactly as ``semdp-train`` builds it (same configs, same vector env),
runs ``epochs`` epochs after one warm-up epoch, and the table reports env steps per second of
training (rollout + update, no evaluation) -- the ``fps`` column of ``progress.csv``. Results
are also written to ``outputs/bench/train_<env>.csv``. Machine load changes the figures: report
the machine with them.
"""

from __future__ import annotations

import csv
import platform
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir

from semdp.paths import CONF_DIR, REPO_ROOT
from semdp.train import build_algorithm

DEFAULTS = {"env": "speed_limit", "algos": "ppo_lag", "epochs": "3", "steps_per_epoch": "10000",
            "num_envs": "", "torch_threads": "1", "out": ""}


def _parse(argv: list[str]) -> dict[str, str]:
    args = dict(DEFAULTS)
    for item in argv:
        key, sep, value = item.partition("=")
        if not sep or key not in DEFAULTS:
            raise SystemExit(
                f"semdp-bench train: bad argument {item!r}; use key=value with keys "
                f"{sorted(DEFAULTS)}"
            )
        args[key] = value
    return args


def measure(env: str, algo: str, epochs: int, steps_per_epoch: int, num_envs: str) -> dict:
    """Build one algorithm as the trainer does and time ``epochs`` epochs after a warm-up."""
    overrides = [f"algo={algo}", f"env={env}", f"budget.steps_per_epoch={steps_per_epoch}"]
    if num_envs:
        overrides.append(f"env.num_envs={num_envs}")
    if algo == "sac":  # measure learning throughput, not the random warm-up
        overrides.append(f"algo.learning_starts={min(1000, steps_per_epoch)}")
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=overrides)
    model = build_algorithm(cfg)
    model.total_epochs = epochs + 1
    model.train_epoch()  # warm-up (SAC: fills the buffer past learning_starts)
    start, steps0 = time.perf_counter(), model.env_steps
    for _ in range(epochs):
        model.train_epoch()
    elapsed = time.perf_counter() - start
    steps = model.env_steps - steps0
    return {"env": env, "algo": algo, "num_envs": model.num_envs, "env_steps": steps,
            "seconds": round(elapsed, 3), "fps": round(steps / elapsed, 1)}


def main(argv: list[str]) -> None:
    """Print the throughput table and write the CSV."""
    args = _parse(argv)
    torch.set_num_threads(int(args["torch_threads"]))
    rows = [
        measure(args["env"], algo, int(args["epochs"]), int(args["steps_per_epoch"]),
                args["num_envs"])
        for algo in args["algos"].split(",")
    ]
    print(f"training throughput on {platform.node()} ({platform.processor() or 'cpu'}), "
          f"torch threads {args['torch_threads']}")
    print(f"{'algo':<12} {'env':<14} {'envs':>5} {'steps':>8} {'s':>8} {'steps/s':>9}")
    for r in rows:
        print(f"{r['algo']:<12} {r['env']:<14} {r['num_envs']:>5} {r['env_steps']:>8} "
              f"{r['seconds']:>8.2f} {r['fps']:>9.0f}")
    out = Path(args["out"]) if args["out"] else REPO_ROOT / "outputs" / "bench" / \
        f"train_{args['env']}.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {out}")
