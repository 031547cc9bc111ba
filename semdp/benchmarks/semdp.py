"""``semdp-bench semdp``: training throughput of the Safety-Embedded MDP main job and where its
time goes (thesis Alg. 2: perceive, plan, follow k steps, simulate; SAC learns).

    semdp-bench semdp                                   # experiment=semdp as configured
    semdp-bench semdp env=semdp_point_push1 steps=6000
    semdp-bench semdp loop=sequential                   # the one-env, update-after-each-step loop
    semdp-bench semdp env.num_envs=2 algo.learner=inline
    semdp-bench semdp random=true                       # the envs alone: random actions, no SAC

Any ``key=value`` other than the bench's own (``steps``, ``out``) is a Hydra override of the
``semdp-train experiment=semdp`` config. The algorithm is built as ``semdp-train`` builds it,
runs its uniformly random steps (``algo.learning_starts``, untimed), then ``steps``
high-level steps of learning in whole epochs, without evaluation. ``random=true`` times the
envs alone (the training process's side of the loop without acting and learning): uniformly
random actions throughout, no learner, one untimed epoch first. Printed: high-level and env
steps/s and the wall-time split -- perception, planning, following, simulation (inside the
SEMDP envs), learning (in the training process: the updates, or the wait for the learner
process), other (acting, replay, bookkeeping) -- how busy a learner process was, and the CPU
milliseconds per high-level step of each process (load-independent: with a core per process,
the slower one sets the pace). Results are appended to ``outputs/bench/semdp.csv``. Report the
machine load with the figures.
"""

from __future__ import annotations

import csv
import math
import os
import platform
import time
from pathlib import Path
from typing import Any

import torch

from semdp.benchmarks.arguments import BenchArgumentError, as_bool, as_int, parse_args
from semdp.build import build_algorithm
from semdp.configs import compose_config
from semdp.embedded.timing import timing_summary
from semdp.paths import REPO_ROOT

BENCH_KEYS = {"steps": "4000", "out": "", "random": "false"}
PARTS: tuple[tuple[str, str], ...] = (
    ("perception", "perception_s"), ("planning", "plan_s"), ("following", "follow_s"),
    ("simulation", "sim_s"),
)


def _parse(argv: list[str]) -> tuple[dict[str, str], list[str]]:
    """The bench's own keys, and the rest as Hydra overrides."""
    own = [item for item in argv if item.partition("=")[0] in BENCH_KEYS]
    overrides = [item for item in argv if item not in own]
    for item in overrides:
        if "=" not in item:
            raise BenchArgumentError(
                f"semdp-bench semdp: bad argument {item!r}; use key=value (bench keys "
                f"{sorted(BENCH_KEYS)}, anything else is a Hydra override)")
    return parse_args("semdp", own, BENCH_KEYS), overrides


#: ``algo.learning_starts`` of ``random=true``: never reached.
NEVER = 10**15


def measure(steps: int, overrides: list[str], random: bool = False) -> dict[str, Any]:
    """Build the main job's algorithm, pass ``learning_starts``, time ``steps`` more steps
    (``random``: random actions throughout, after one untimed epoch)."""
    if not any(o.startswith("experiment=") for o in overrides):
        overrides = ["experiment=semdp", *overrides]
    extra = [f"algo.learning_starts={NEVER}"] if random else []
    cfg = compose_config("train", [*overrides, *extra, "tensorboard=false"])
    torch.set_num_threads(int(cfg.torch_threads))
    algo = build_algorithm(cfg)
    try:
        if random:
            algo.train_epoch()
        while algo.env_steps < int(cfg.algo.learning_starts) and not random:
            algo.train_epoch()
        epochs = max(1, math.ceil(steps / algo.steps_per_epoch))
        inside0, learn0 = timing_summary([algo.envs]), dict(getattr(algo, "timing", {}))
        steps0 = algo.env_steps
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for _ in range(epochs):
            algo.train_epoch()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        inside1, learn1 = timing_summary([algo.envs]), dict(getattr(algo, "timing", {}))
    finally:
        close = getattr(algo, "close", None)
        if close is not None:
            close()
    high = algo.env_steps - steps0
    low = inside1["low_level_steps"] - inside0["low_level_steps"]

    def delta(key: str) -> float:
        return float(learn1.get(key, 0.0) - learn0.get(key, 0.0))

    split = {name: inside1[key] - inside0[key] for name, key in PARTS}
    split["learning"] = delta("learner_wait_s")
    split["other"] = max(wall - sum(split.values()), 0.0)
    return {
        "env": str(cfg.env.id), "num_envs": algo.num_envs,
        "learner": "none (random actions)" if random else str(cfg.algo.get("learner",
                                                                              "sequential")),
        "seed": int(cfg.seed),
        "high_level_steps": high, "env_steps": int(low), "wall_s": wall, "cpu_s": cpu,
        "high_level_steps_per_s": high / wall, "env_steps_per_s": low / wall,
        **{f"{name}_s": value for name, value in split.items()},
        "learner_busy_s": delta("learner_busy_s") if cfg.algo.get("learner") == "process"
        else split["learning"],
        "learner_cpu_s": delta("learner_cpu_s"),
        "load_1min": os.getloadavg()[0], "overrides": " ".join([*overrides, *extra]),
    }


def main(argv: list[str]) -> None:
    """Print the throughput and the time split; append them to the CSV."""
    args, overrides = _parse(argv)
    args_random = as_bool(args, "random")
    row = measure(as_int(args, "steps", minimum=1), overrides, args_random)
    wall, high = row["wall_s"], row["high_level_steps"]
    print(f"SEMDP training throughput on {platform.node()} ({os.cpu_count()} CPUs), "
          f"load {row['load_1min']:.2f}: {row['env']}, {row['num_envs']} env(s), learner "
          f"{row['learner']}, {high} high-level steps "
          f"{'of random actions' if args_random else 'after the random ones'}")
    print(f"  {row['high_level_steps_per_s']:.0f} high-level steps/s, "
          f"{row['env_steps_per_s']:.0f} env steps/s (wall {wall:.1f} s, training process "
          f"CPU {row['cpu_s']:.1f} s)")
    print(f"  {'part':<11} {'s':>7} {'%':>6} {'ms/step':>8}")
    for name in ("perception", "planning", "following", "simulation", "learning", "other"):
        value = row[f"{name}_s"]
        print(f"  {name:<11} {value:>7.2f} {100 * value / wall:>6.1f} {1e3 * value / high:>8.3f}")
    if row["learner"] == "process":
        print(f"  learner process busy {row['learner_busy_s']:.1f} s "
              f"({100 * row['learner_busy_s'] / wall:.0f} % of the wall time), CPU "
              f"{row['learner_cpu_s']:.1f} s")
    # Load-independent: CPU ms per high-level step of each process; on a quiet machine with a
    # core per process the slower of the two sets the pace.
    learner_ms = 1e3 * row["learner_cpu_s"] / high
    print(f"  CPU per high-level step: training process {1e3 * row['cpu_s'] / high:.2f} ms"
          + (f", learner process {learner_ms:.2f} ms" if row["learner"] == "process" else ""))
    out = Path(args["out"]) if args["out"] else REPO_ROOT / "outputs" / "bench" / "semdp.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    new = not out.exists()
    with out.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(row))
        if new:
            writer.writeheader()
        writer.writerow({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()})
    print(f"appended to {out}")
