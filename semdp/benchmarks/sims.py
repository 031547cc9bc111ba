"""``semdp-bench sims``: env steps/s of the Safety Gym replica, and its calibration table.

For each robot x task at one level (default 1) it times random-action steps (actions drawn
beforehand; resets at episode ends included) through ``gymnasium.make`` (single env, with the
usual wrappers) and through gymnasium vector envs (sync and async), prints a markdown table and
writes a CSV. ``--calibration`` prints the robot responses against Safety-Gymnasium's measured
tables (spec file §3). Examples::

    semdp-bench sims
    semdp-bench sims --steps 20000 --num-envs 8 --csv outputs/bench/sims.csv
    semdp-bench sims --robots point --tasks push --no-vector
    semdp-bench sims --calibration
"""

from __future__ import annotations

import argparse
import csv
import platform
import time
from pathlib import Path

import gymnasium
import numpy as np

import sims  # noqa: F401  (registers the ids)
from sims.safety_gym.calibration import calibration_table, format_table
from sims.safety_gym.config import LEVELS, ROBOTS, TASKS, env_id

#: Safety-Gymnasium 1.0.0 (MuJoCo) SafetyPointPush1-v0, measured on this machine kind (SPEC §3.1).
MUJOCO_POINT_PUSH1_STEPS_PER_S = 390.0


def time_single(name: str, steps: int, seed: int = 0) -> float:
    """Steps/s of one ``gymnasium.make`` env under random actions (resets included)."""
    env = gymnasium.make(name)
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, (steps, 2))
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def time_vector(name: str, steps: int, num_envs: int, mode: str, seed: int = 0) -> float:
    """Env steps/s (summed over sub-envs) of a gymnasium vector env (autoreset)."""
    envs = gymnasium.make_vec(name, num_envs=num_envs, vectorization_mode=mode)
    envs.reset(seed=seed)
    batches = max(1, steps // num_envs)
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, (batches, num_envs, 2))
    start = time.perf_counter()
    for action in actions:
        envs.step(action)
    elapsed = time.perf_counter() - start
    envs.close()
    return batches * num_envs / elapsed


def main(argv: list[str]) -> None:
    """Run the benchmark (see the module docstring for the options)."""
    parser = argparse.ArgumentParser(prog="semdp-bench sims", description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=20000, help="env steps per measurement")
    parser.add_argument("--level", type=int, default=1, choices=LEVELS)
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--num-envs", type=int, default=8, help="sub-envs of the vector envs")
    parser.add_argument("--no-vector", action="store_true", help="single env only")
    parser.add_argument("--no-async", action="store_true", help="skip the async vector env")
    parser.add_argument("--csv", type=Path, default=Path("outputs/bench/sims.csv"))
    parser.add_argument("--calibration", action="store_true", help="print the calibration table")
    args = parser.parse_args(argv)
    if args.steps < 1 or args.num_envs < 1:
        parser.error("--steps and --num-envs must be positive")

    if args.calibration:
        print("Robot responses, ours vs Safety-Gymnasium 1.0.0 (measured):\n")
        print(format_table(calibration_table()))
        return

    rows = []
    header = ["env", "single_steps_per_s", "vs_mujoco", "sync_steps_per_s", "async_steps_per_s"]
    for robot in args.robots:
        for task in args.tasks:
            name = env_id(robot, task, args.level)
            single = time_single(name, args.steps)
            sync = async_ = float("nan")
            if not args.no_vector:
                sync = time_vector(name, args.steps, args.num_envs, "sync")
                if not args.no_async:
                    async_ = time_vector(name, args.steps, args.num_envs, "async")
            row = [name, single, single / MUJOCO_POINT_PUSH1_STEPS_PER_S, sync, async_]
            rows.append(row)
            print(f"{name:32s} {single:10.0f} steps/s", flush=True)

    print(f"\n{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"{args.steps} steps each, vector envs with {args.num_envs} sub-envs\n")  # fmt: skip
    print("| env | single env (steps/s) | × MuJoCo PointPush1 (390/s) | sync vector "
          "| async vector |")  # fmt: skip
    print("|---|---|---|---|---|")
    for name, single, ratio, sync, async_ in rows:
        print(f"| {name} | {single:,.0f} | {ratio:.0f}× | {sync:,.0f} | {async_:,.0f} |")
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with args.csv.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    print(f"\nwrote {args.csv}")
