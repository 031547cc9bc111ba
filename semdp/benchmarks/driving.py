"""``semdp-bench driving``: env speed and the hand controller across desired speeds (App. A.2).

Two measurements, printed as tables and written to one CSV (``section`` column):

* ``speed`` -- single-env steps/s of ``sims/DriveCircle-v0`` and ``sims/DriveTrajectory-v0``
  with uniformly random actions, automatic resets included; ``raw`` is the bare env,
  ``gym.make`` adds gymnasium's default wrappers. Median over ``repeats``.
* ``controller`` -- :class:`sims.driving.PurePursuitController` (pure pursuit + speed
  P-control) on both tasks at each desired speed: return (Eq. A.1) and cost (Eq. A.2) per
  episode, mean and standard deviation over ``episodes`` seeded episodes.

Usage (``key=value`` arguments, :mod:`semdp.benchmarks.arguments`)::

    semdp-bench driving [steps=20000] [repeats=3] [episodes=10] [speeds=[1,2,3,4,5,6]]
                        [out=outputs/bench/driving.csv]
"""

from __future__ import annotations

import csv
import statistics
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import sims  # noqa: F401  (registers the env ids)
from semdp.benchmarks.arguments import as_float, as_int, as_items, parse_args
from sims.driving import PurePursuitController, run_episode

ENV_IDS = ("sims/DriveCircle-v0", "sims/DriveTrajectory-v0")
DEFAULTS: dict[str, str] = {
    "steps": "20000",
    "repeats": "3",
    "episodes": "10",
    "speeds": "[1,2,3,4,5,6]",
    "out": "outputs/bench/driving.csv",
}
COLUMNS = ("section", "env_id", "variant", "desired_speed", "episodes", "steps_per_s",
           "return_mean", "return_std", "cost_mean", "cost_std", "cost_episode_fraction",
           "termination_fraction", "mean_speed")


def steps_per_second(env: gym.Env, steps: int, seed: int = 0) -> float:
    """Single-env steps/s with pre-drawn random actions, resets included."""
    actions = np.random.default_rng(seed).uniform(-1, 1, size=(1024, 2)).astype(np.float32)
    env.reset(seed=seed)
    start = time.perf_counter()
    for i in range(steps):
        _, _, terminated, truncated, _ = env.step(actions[i & 1023])
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def measure_speed(steps: int, repeats: int) -> list[dict[str, object]]:
    """Rows of the ``speed`` section."""
    rows: list[dict[str, object]] = []
    for env_id in ENV_IDS:
        for variant in ("raw", "gym.make"):
            env = gym.make(env_id)
            target = env.unwrapped if variant == "raw" else env
            rates = [steps_per_second(target, steps, seed) for seed in range(repeats)]
            rows.append({"section": "speed", "env_id": env_id, "variant": variant,
                         "steps_per_s": round(statistics.median(rates))})
    return rows


def evaluate_controller(speeds: list[float], episodes: int) -> list[dict[str, object]]:
    """Rows of the ``controller`` section."""
    controller = PurePursuitController()
    rows: list[dict[str, object]] = []
    for env_id in ENV_IDS:
        for speed in speeds:
            env = gym.make(env_id, desired_speed=speed).unwrapped
            results = [run_episode(env, controller, seed) for seed in range(episodes)]
            returns = [r["return"] for r in results]
            costs = [r["cost"] for r in results]
            rows.append({
                "section": "controller", "env_id": env_id, "variant": "pure_pursuit",
                "desired_speed": speed, "episodes": episodes,
                "return_mean": round(statistics.fmean(returns), 3),
                "return_std": round(statistics.pstdev(returns), 3),
                "cost_mean": round(statistics.fmean(costs), 3),
                "cost_std": round(statistics.pstdev(costs), 3),
                "cost_episode_fraction": round(sum(c > 0 for c in costs) / episodes, 3),
                "termination_fraction": round(
                    statistics.fmean(r["terminated"] for r in results), 3),
                "mean_speed": round(statistics.fmean(r["mean_speed"] for r in results), 3),
            })
    return rows


def main(argv: list[str]) -> None:
    """Run the suite, print both tables, write the CSV."""
    options = parse_args("driving", argv, DEFAULTS)
    speeds = [as_float({"speeds": v}, "speeds") for v in as_items(options, "speeds")]
    steps, repeats, episodes = (as_int(options, k, minimum=1)
                                for k in ("steps", "repeats", "episodes"))

    speed_rows = measure_speed(steps, repeats)
    print(f"env steps/s, single env, random actions, {steps} steps, median of {repeats}")
    print(f"{'env':28s} {'variant':10s} {'steps/s':>9s}")
    for row in speed_rows:
        print(f"{row['env_id']!s:28s} {row['variant']!s:10s} {row['steps_per_s']:>9}")

    controller_rows = evaluate_controller(speeds, episodes)
    print(f"\npure pursuit + speed P-control, {episodes} episodes per row "
          f"(seeds 0..{episodes - 1})")
    print(f"{'env':28s} {'v_d':>4s} {'return':>18s} {'cost':>16s} {'P(cost>0)':>9s} "
          f"{'P(term)':>7s} {'speed':>6s}")
    for row in controller_rows:
        print(f"{row['env_id']!s:28s} {row['desired_speed']:>4g} "
              f"{row['return_mean']:>9.2f} ± {row['return_std']:<6.2f} "
              f"{row['cost_mean']:>7.3f} ± {row['cost_std']:<6.3f} "
              f"{row['cost_episode_fraction']:>9.2f} {row['termination_fraction']:>7.2f} "
              f"{row['mean_speed']:>6.2f}")

    out = Path(options["out"])
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(speed_rows + controller_rows)
    print(f"\nwrote {out}")
