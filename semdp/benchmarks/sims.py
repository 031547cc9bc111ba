"""``semdp-bench sims``: env steps/s of the Safety Gym replica, and its calibration table.

For each robot x task at one level (default 1) it times random-action steps (actions drawn
beforehand; resets at episode ends included) through ``gymnasium.make`` (single env, with the
usual wrappers) and through gymnasium vector envs (sync and async), prints a markdown table and
writes a CSV. ``--calibration`` prints the robot responses against Safety-Gymnasium's measured
tables (docs/simulators.md, "Robots and calibration"). ``key=value`` arguments
(:mod:`semdp.benchmarks.arguments`, which also reads the ``--num-envs 8`` spelling)::

    semdp-bench sims
    semdp-bench sims steps=20000 num_envs=8 csv=outputs/bench/sims.csv
    semdp-bench sims robots=point tasks=push vector=false
    semdp-bench sims calibration=true
"""

from __future__ import annotations

import csv
import platform
import time
from pathlib import Path

import gymnasium
import numpy as np

import sims  # noqa: F401  (registers the ids)
from semdp.benchmarks.arguments import BenchArgumentError, as_bool, as_choices, as_int, parse_args
from sims.safety_gym.calibration import calibration_table, format_table
from sims.safety_gym.config import LEVELS, ROBOTS, TASKS, env_id

#: Safety-Gymnasium 1.0.0 (MuJoCo) SafetyPointPush1-v0, measured on this machine kind
#: (docs/simulators.md, "Speed").
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


#: Keys and defaults: env steps per measurement, level, robots, tasks, sub-envs of the vector
#: envs, whether to time the vector envs and the async one, the CSV, the calibration table only.
DEFAULTS: dict[str, str] = {
    "steps": "20000", "level": "1", "robots": ",".join(ROBOTS), "tasks": ",".join(TASKS),
    "num_envs": "8", "vector": "true", "async": "true", "csv": "outputs/bench/sims.csv",
    "calibration": "false",
}  # fmt: skip


def main(argv: list[str]) -> None:
    """Run the benchmark (see the module docstring for the options)."""
    args = parse_args("sims", argv, DEFAULTS)
    if as_bool(args, "calibration"):
        print("Robot responses, ours vs Safety-Gymnasium 1.0.0 (measured):\n")
        print(format_table(calibration_table()))
        return
    steps, num_envs = as_int(args, "steps", minimum=1), as_int(args, "num_envs", minimum=1)
    level = as_int(args, "level")
    if level not in LEVELS:
        raise BenchArgumentError(f"semdp-bench sims: level must be one of {LEVELS}, got {level}")
    robots, tasks = as_choices(args, "robots", ROBOTS), as_choices(args, "tasks", TASKS)
    vector, async_vector = as_bool(args, "vector"), as_bool(args, "async")
    csv_path = Path(args["csv"])

    rows = []
    header = ["env", "single_steps_per_s", "vs_mujoco", "sync_steps_per_s", "async_steps_per_s"]
    for robot in robots:
        for task in tasks:
            name = env_id(robot, task, level)
            single = time_single(name, steps)
            sync = async_ = float("nan")
            if vector:
                sync = time_vector(name, steps, num_envs, "sync")
                if async_vector:
                    async_ = time_vector(name, steps, num_envs, "async")
            row = [name, single, single / MUJOCO_POINT_PUSH1_STEPS_PER_S, sync, async_]
            rows.append(row)
            print(f"{name:32s} {single:10.0f} steps/s", flush=True)

    print(f"\n{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"{steps} steps each, vector envs with {num_envs} sub-envs\n")  # fmt: skip
    print("| env | single env (steps/s) | × MuJoCo PointPush1 (390/s) | sync vector "
          "| async vector |")  # fmt: skip
    print("|---|---|---|---|---|")
    for name, single, ratio, sync, async_ in rows:
        print(f"| {name} | {single:,.0f} | {ratio:.0f}× | {sync:,.0f} | {async_:,.0f} |")
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    print(f"\nwrote {csv_path}")
