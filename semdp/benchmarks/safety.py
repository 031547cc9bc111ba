"""``semdp-bench safety``: is the Safety-Embedded MDP safe whatever the high level does?

The thesis' safety argument (§3.5.2) puts safety in the planner, not in the learned policy, so
it must hold for any subgoal sequence. This drives each robot x task with two high-level
policies that were never trained, under the evaluation configuration (the env's
``eval_wrapper``) and the training configuration (``wrapper``), and counts what leaks:

* ``random``: uniformly random subgoals in the ego frame (+-2 m);
* ``adversarial``: every subgoal aimed at the nearest hazard (ground truth), 2 m away at most.

    semdp-bench safety                       # 3 robots x 4 tasks x 2 x 2 cells, 20 episodes
    semdp-bench safety robots=car tasks=Push2 policies=adversarial configs=eval episodes=5
    semdp-bench safety robots=point tasks=Push1 planner@env.planner=ipopt    # + Hydra overrides

Prints one row per cell (episodes with cost, cost steps, fallback %, escape %, rescue % of the
high-level steps, shield % of the low-level steps whose command the safety filter replaced,
high-level steps/s, violation sources) and writes ``safety.csv`` / ``safety.json`` under
``out=`` (default ``outputs/bench/safety_<time>``). Episodes are seeded ``seed + i`` (default
seed 7000: not a seed range any setting was tuned on).
"""

from __future__ import annotations

import csv
import json
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from hydra.utils import instantiate
from omegaconf import OmegaConf

from semdp.benchmarks.arguments import as_int, parse_args
from semdp.configs import compose_config
from semdp.embedded.safety_eval import evaluate_safety
from semdp.embedded.tracking import world_to_ego
from semdp.embedded.wrapper import SafetyEmbeddedEnv

ROBOTS = ("point", "car", "mass")
TASKS = ("Goal1", "Goal2", "Push1", "Push2")
POLICIES = ("random", "adversarial")
CONFIGS = ("eval", "train")


@dataclass(frozen=True)
class Cell:
    """One robot x task x policy x configuration of the table."""

    robot: str
    task: str
    policy: str
    config: str
    episodes: int
    seed: int
    overrides: tuple[str, ...] = ()


def build_semdp_env(robot: str, task: str, config: str,
                    overrides: tuple[str, ...] = ()) -> SafetyEmbeddedEnv:
    """The SEMDP env ``env=semdp_<robot>_<task>`` as composed by Hydra, with its
    evaluation (``config="eval"``) or training (``"train"``) wrapper."""
    cfg = compose_config("train", ["algo=sac", f"env=semdp_{robot}_{task.lower()}", *overrides])
    env_cfg = OmegaConf.to_container(cfg.env, resolve=True)
    assert isinstance(env_cfg, dict)
    node = env_cfg["eval_wrapper" if config == "eval" else "wrapper"]
    return instantiate(node)(gym.make(env_cfg["id"], **env_cfg["kwargs"]))


def make_policy(kind: str, env: SafetyEmbeddedEnv, seed: int) -> Callable[[np.ndarray], np.ndarray]:
    """A high-level policy ``obs -> action`` that was never trained (see the module docstring)."""
    rng = np.random.default_rng(seed)
    if kind == "random":
        return lambda _obs: rng.uniform(-1.0, 1.0, size=2)
    if kind != "adversarial":
        raise ValueError(f"policy must be one of {POLICIES}, got {kind!r}")
    base = env.unwrapped

    def aim_at_nearest_hazard(_obs: np.ndarray) -> np.ndarray:
        hazards = np.asarray(base.obstacles(kinds=("hazards",))).reshape(-1, 3)
        if not len(hazards):  # no hazard in this task: aim at the nearest obstacle of any kind
            hazards = np.asarray(base.obstacles(kinds=env.obstacle_kinds)).reshape(-1, 3)
        if not len(hazards):
            return rng.uniform(-1.0, 1.0, size=2)
        position = np.asarray(base.robot_position, dtype=float)
        nearest = hazards[np.argmin(np.linalg.norm(hazards[:, :2] - position, axis=1)), :2]
        ego = world_to_ego(nearest - position, base.robot_heading) / env.subgoal_scale
        return np.clip(ego, -1.0, 1.0)

    return aim_at_nearest_hazard


def run_cell(cell: Cell) -> dict[str, Any]:
    """Evaluate one cell; a row of the table."""
    import torch

    torch.set_num_threads(1)
    env = build_semdp_env(cell.robot, cell.task, cell.config, cell.overrides)
    stats = evaluate_safety(env, make_policy(cell.policy, env, cell.seed), cell.episodes,
                            seed=cell.seed)
    return {**asdict(cell), **{k: v for k, v in stats.items() if k != "violations"},
            "violations": stats["violations"][:5]}


#: The suite's keys and defaults (``out`` empty: a time-stamped folder in outputs/bench).
DEFAULTS: dict[str, str] = {
    "robots": ",".join(ROBOTS), "tasks": ",".join(TASKS), "policies": ",".join(POLICIES),
    "configs": ",".join(CONFIGS), "episodes": "20", "seed": "7000", "workers": "2", "out": "",
}


def _parse(argv: list[str]) -> tuple[dict[str, str], list[str]]:
    """``key=value`` arguments of this suite (:mod:`semdp.benchmarks.arguments`), and Hydra
    overrides of the train config (keys with ``.`` or ``@``, or starting with ``+``)."""
    own, overrides = [], []
    for item in argv:
        key, sep, _ = item.partition("=")
        hydra = sep and key not in DEFAULTS and ("." in key or "@" in key or key.startswith("+"))
        (overrides if hydra else own).append(item)
    return parse_args("safety", own, DEFAULTS), overrides


def _choice(value: str, valid: tuple[str, ...], what: str) -> tuple[str, ...]:
    items = tuple(v.strip() for v in value.split(",") if v.strip())
    bad = [v for v in items if v not in valid]
    if bad or not items:
        raise ValueError(f"{what} must be a comma list of {valid}, got {value!r}")
    return items


def format_table(rows: list[dict[str, Any]]) -> str:
    """The printed table: one line per cell."""
    head = (f"{'robot':6} {'task':6} {'policy':11} {'config':6} {'ep w/ cost':>10} "
            f"{'cost steps':>10} {'fallback%':>9} {'escape%':>8} {'rescue%':>8} {'shield%':>8}"
            f" {'hl/s':>6}  sources")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['robot']:6} {r['task']:6} {r['policy']:11} {r['config']:6} "
            f"{r['episodes_with_cost']:>4}/{r['episodes']:<5} {r['cost_steps_total']:>10.0f} "
            f"{100 * r['fallback_rate']:>9.1f} {100 * r['escape_rate']:>8.1f} "
            f"{100 * r['rescue_rate']:>8.1f} {100 * r['shield_rate']:>8.2f} "
            f"{r['high_level_steps_per_s']:>6.0f}  "
            f"{r['violation_windows_by_source'] or ''}")
    return "\n".join(lines)


def markdown_table(rows: list[dict[str, Any]], seed: int, episodes: int) -> str:
    """The table for a README: one row per robot x task, the four policy x config cells as
    ``episodes with cost / episodes`` and the fallback, escape, rescue and shield rates."""
    lines = [f"Episodes with cost / episodes (seeds {seed}..{seed + episodes - 1}); fallback, "
             "escape and rescue % of the plans and shield % of the low-level commands, over "
             "the four cells; high-level steps/s (mean of the cells).", "",
             "| robot | task | random, eval | random, train | adversarial, eval | "
             "adversarial, train | cost steps | fallback % | escape % | rescue % | shield % | "
             "hl steps/s |", "|" + "---|" * 12]
    cells: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        cells.setdefault((row["robot"], row["task"]), []).append(row)
    for (robot, task), group in cells.items():
        by = {(r["policy"], r["config"]): r for r in group}
        shown = [by.get((p, c)) for p in POLICIES for c in CONFIGS]
        marks = [f"{r['episodes_with_cost']}/{r['episodes']}" if r else "–" for r in shown]

        def rate(key: str, rows: list[dict[str, Any]] = group) -> str:
            total = sum(r["plans"] for r in rows)
            return f"{100 * sum(r[key] * r['plans'] for r in rows) / max(total, 1):.1f}"

        lines.append(
            f"| {robot.capitalize()} | {task} | {' | '.join(marks)} | "
            f"{sum(r['cost_steps_total'] for r in group):.0f} | {rate('fallback_rate')} | "
            f"{rate('escape_rate')} | {rate('rescue_rate')} | "
            f"{100 * sum(r['shield_rate'] for r in group) / len(group):.2f} | "
            f"{sum(r['high_level_steps_per_s'] for r in group) / len(group):.0f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    """CLI: see the module docstring."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args, overrides = _parse(argv)
        robots = _choice(args["robots"], ROBOTS, "robots")
        tasks = _choice(args["tasks"], TASKS, "tasks")
        policies = _choice(args["policies"], POLICIES, "policies")
        configs = _choice(args["configs"], CONFIGS, "configs")
        episodes, seed = as_int(args, "episodes", minimum=1), as_int(args, "seed")
        workers = as_int(args, "workers", minimum=1)
    except ValueError as exc:
        sys.exit(f"semdp-bench safety: {exc}")
    out = Path(args["out"] or f"outputs/bench/safety_{time.strftime('%Y-%m-%d_%H-%M-%S')}")
    cells = [Cell(r, t, p, c, episodes, seed, tuple(overrides))
             for r in robots for t in tasks for p in policies for c in configs]
    tic = time.perf_counter()
    if workers == 1:
        rows = [run_cell(c) for c in cells]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            rows = list(pool.map(run_cell, cells))
    print(format_table(rows))
    leaks = sum(r["episodes_with_cost"] for r in rows)
    print(f"{len(rows)} cells, {len(rows) * episodes} episodes (seeds {seed}.."
          f"{seed + episodes - 1}), {leaks} with cost; {time.perf_counter() - tic:.0f} s, "
          f"{workers} workers")
    out.mkdir(parents=True, exist_ok=True)
    (out / "safety.json").write_text(json.dumps(rows, indent=2, default=float))
    columns = [k for k in rows[0] if k not in ("violations", "violation_windows_by_source",
                                               "overrides")]
    with (out / "safety.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=[*columns, "sources"])
        writer.writeheader()
        for r in rows:
            writer.writerow({**{k: r[k] for k in columns},
                             "sources": json.dumps(r["violation_windows_by_source"])})
    (out / "safety.md").write_text(markdown_table(rows, seed, episodes))
    print(f"wrote {out / 'safety.csv'} and safety.md")
