"""``semdp-bench safety``: is the Safety-Embedded MDP safe whatever the high level does?

The thesis' safety argument (§3.5.2) puts safety in the planner, not in the learned policy, so
it must hold for any subgoal sequence. This drives each robot x task (the three Safety Gym task
families Goal, Button and Push at levels 1 and 2) with high-level policies that were never
trained, under the evaluation configuration (the env's ``eval_wrapper``) and the training
configuration (``wrapper``), and counts what leaks:

* ``random``: uniformly random subgoals in the ego frame (+-2 m);
* ``adversarial`` (hazard-seeking): every subgoal aimed at the nearest hazard (ground truth),
  2 m away at most;
* ``wrong_button`` (Button tasks only; the other tasks have no such cell): every subgoal aimed
  at the nearest button that is not the goal button (ground truth), 2 m away at most;
* ``goal`` (Button tasks only): every subgoal aimed at the goal button, 2 m away at most -- what
  a trained high level does: it presses button after button, so every episode crosses the grace
  period (the robot on the button just pressed, which is a wrong button once the goal moves).

    semdp-bench safety                       # 3 robots x 6 tasks x 2-3 x 2 cells, 20 episodes
    semdp-bench safety robots=car tasks=Push2 policies=adversarial configs=eval episodes=5
    semdp-bench safety robots=mass tasks=Button1 policies=wrong_button episodes=5
    semdp-bench safety robots=point tasks=Push1 planner@env.planner=ipopt    # + Hydra overrides

Prints one row per cell (episodes with cost, cost steps, fallback %, escape %, rescue % of the
high-level steps, shield % of the low-level steps whose command the safety filter replaced,
high-level steps/s, violation sources) and writes ``safety.csv`` / ``safety.json`` under
``out=`` (default ``outputs/bench/safety_<time>``). Each finished cell is appended to
``cells.jsonl`` there first, so a run cut short is continued by the same command with the same
``out=`` (its finished cells are read back, not run again). Episodes are seeded ``seed + i``
(default seed 7000: not a seed range any setting was tuned on).
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
from semdp.embedded.perception import perceive_obstacles, wrong_buttons
from semdp.embedded.tracking import world_to_ego
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.evaluation.safety_eval import evaluate_safety

ROBOTS = ("point", "car", "mass")
TASKS = ("Goal1", "Goal2", "Button1", "Button2", "Push1", "Push2")
POLICIES = ("random", "adversarial", "wrong_button", "goal")
#: Policies that only apply to some tasks (their cells exist for those tasks only).
POLICY_TASKS: dict[str, tuple[str, ...]] = {"wrong_button": ("Button1", "Button2"),
                                             "goal": ("Button1", "Button2")}
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
    evaluation (``config="eval"``) or training (``"train"``) wrapper. A task without its own
    option (the Button tasks, unless registered) is ``env=semdp_<robot>_push1 env.task=<task>``:
    the same node with the task replaced."""
    from semdp.env_products import SEMDP_TASKS

    if task.lower() in SEMDP_TASKS:
        env = [f"env=semdp_{robot}_{task.lower()}"]
    else:
        env = [f"env=semdp_{robot}_push1", f"env.task={task}"]
    cfg = compose_config("train", ["algo=sac", *env, *overrides])
    env_cfg = OmegaConf.to_container(cfg.env, resolve=True)
    assert isinstance(env_cfg, dict)
    node = env_cfg["eval_wrapper" if config == "eval" else "wrapper"]
    return instantiate(node)(gym.make(env_cfg["id"], **env_cfg["kwargs"]))


def make_policy(kind: str, env: SafetyEmbeddedEnv, seed: int) -> Callable[[np.ndarray], np.ndarray]:
    """A high-level policy ``obs -> action`` that was never trained (see the module docstring)."""
    rng = np.random.default_rng(seed)
    if kind == "random":
        return lambda _obs: rng.uniform(-1.0, 1.0, size=2)
    if kind not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {kind!r}")
    base = env.unwrapped

    def targets() -> np.ndarray:
        if kind == "wrong_button":
            return wrong_buttons(base)
        if kind == "goal":
            return np.asarray(base.goal_position, dtype=float).reshape(1, 2)
        hazards = np.asarray(base.obstacles(kinds=("hazards",))).reshape(-1, 3)
        if not len(hazards):  # no hazard in this task: aim at the nearest obstacle of any kind
            hazards = perceive_obstacles(base, np.zeros(0), "gt", env.obstacle_kinds)
        return hazards

    def aim_at_nearest(_obs: np.ndarray) -> np.ndarray:
        found = targets()
        if not len(found):
            return rng.uniform(-1.0, 1.0, size=2)
        position = np.asarray(base.robot_position, dtype=float)
        nearest = found[np.argmin(np.linalg.norm(found[:, :2] - position, axis=1)), :2]
        ego = world_to_ego(nearest - position, base.robot_heading) / env.subgoal_scale
        return np.clip(ego, -1.0, 1.0)

    return aim_at_nearest


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
    head = (f"{'robot':6} {'task':7} {'policy':12} {'config':6} {'ep w/ cost':>10} "
            f"{'cost steps':>10} {'fallback%':>9} {'escape%':>8} {'rescue%':>8} {'shield%':>8}"
            f" {'hl/s':>6}  sources")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['robot']:6} {r['task']:7} {r['policy']:12} {r['config']:6} "
            f"{r['episodes_with_cost']:>4}/{r['episodes']:<5} {r['cost_steps_total']:>10.0f} "
            f"{100 * r['fallback_rate']:>9.1f} {100 * r['escape_rate']:>8.1f} "
            f"{100 * r['rescue_rate']:>8.1f} {100 * r['shield_rate']:>8.2f} "
            f"{r['high_level_steps_per_s']:>6.0f}  "
            f"{r['violation_windows_by_source'] or ''}")
    return "\n".join(lines)


def markdown_table(rows: list[dict[str, Any]], seed: int, episodes: int) -> str:
    """The table for a page: one row per robot x task, the policy x config cells as
    ``episodes with cost / episodes`` (– where a policy does not apply) and the fallback,
    escape, rescue and shield rates (the shield's: lowest-highest cell)."""
    policies = [p for p in POLICIES if any(r["policy"] == p for r in rows)]
    heads = [f"{p}, {c}" for p in policies for c in CONFIGS]
    lines = [f"Episodes with cost / episodes (seeds {seed}..{seed + episodes - 1}); fallback, "
             "escape and rescue % of the plans over the row's cells; shield % of the low-level "
             "commands (lowest-highest cell); high-level steps/s (mean of the cells).", "",
             f"| robot | task | {' | '.join(heads)} | cost steps | fallback % | escape % | "
             "rescue % | shield % | hl steps/s |", "|" + "---|" * (len(heads) + 8)]
    cells: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        cells.setdefault((row["robot"], row["task"]), []).append(row)
    for (robot, task), group in cells.items():
        by = {(r["policy"], r["config"]): r for r in group}
        shown = [by.get((p, c)) for p in policies for c in CONFIGS]
        marks = [f"{r['episodes_with_cost']}/{r['episodes']}" if r else "–" for r in shown]

        def rate(key: str, rows: list[dict[str, Any]] = group) -> str:
            total = sum(r["plans"] for r in rows)
            return f"{100 * sum(r[key] * r['plans'] for r in rows) / max(total, 1):.1f}"

        lines.append(
            f"| {robot.capitalize()} | {task} | {' | '.join(marks)} | "
            f"{sum(r['cost_steps_total'] for r in group):.0f} | {rate('fallback_rate')} | "
            f"{rate('escape_rate')} | {rate('rescue_rate')} | "
            f"{100 * min(r['shield_rate'] for r in group):.2f}-"
            f"{100 * max(r['shield_rate'] for r in group):.2f} | "
            f"{sum(r['high_level_steps_per_s'] for r in group) / len(group):.0f} |")
    return "\n".join(lines) + "\n"


def _key(cell: Cell) -> str:
    """A cell's identity in ``cells.jsonl``."""
    return json.dumps(asdict(cell), sort_keys=True)


def _plain(value: Any) -> Any:
    """A NumPy scalar as the Python number it holds (for ``cells.jsonl``)."""
    return value.item() if hasattr(value, "item") else float(value)


def _finished(path: Path) -> dict[str, dict[str, Any]]:
    """The rows of ``cells.jsonl`` by cell (empty if there is none)."""
    if not path.is_file():
        return {}
    records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {record["cell"]: record["row"] for record in records}


def _record(finished: Any, cells: list[Cell], rows: list[dict[str, Any]], out: Path,
            total: int, tic: float) -> None:
    """Append each finished row to ``rows`` and to ``cells.jsonl``, with a progress line."""
    with (out / "cells.jsonl").open("a") as log:
        for cell, row in zip(cells, finished, strict=False):
            rows.append(row)
            log.write(json.dumps({"cell": _key(cell), "row": row}, default=_plain) + "\n")
            log.flush()
            _progress(row, total - len(cells) + len(rows), total, tic)


def _progress(r: dict[str, Any], done: int, total: int, tic: float) -> None:
    """One line on stderr per finished cell (the table is printed at the end)."""
    print(f"[{done}/{total}] {r['robot']} {r['task']} {r['policy']} {r['config']}: "
          f"{r['episodes_with_cost']}/{r['episodes']} episodes with cost, shield "
          f"{100 * r['shield_rate']:.2f} %, {time.perf_counter() - tic:.0f} s",
          file=sys.stderr, flush=True)


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
             for r in robots for t in tasks for p in policies for c in configs
             if t in POLICY_TASKS.get(p, (t,))]
    if not cells:
        sys.exit(f"semdp-bench safety: no cell: policies {','.join(policies)} do not apply to "
                 f"tasks {','.join(tasks)}")
    tic = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    done = _finished(out / "cells.jsonl")
    todo = [c for c in cells if _key(c) not in done]
    rows: list[dict[str, Any]] = []
    if len(todo) < len(cells):
        print(f"{len(cells) - len(todo)} of {len(cells)} cells read back from "
              f"{out / 'cells.jsonl'}", file=sys.stderr, flush=True)
    if workers == 1:
        finished = (run_cell(cell) for cell in todo)
        _record(finished, todo, rows, out, len(cells), tic)
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            _record(pool.map(run_cell, todo), todo, rows, out, len(cells), tic)
    new = {_key(c): row for c, row in zip(todo, rows, strict=True)}
    rows = [done.get(_key(c)) or new[_key(c)] for c in cells]
    print(format_table(rows))
    leaks = sum(r["episodes_with_cost"] for r in rows)
    print(f"{len(rows)} cells, {len(rows) * episodes} episodes (seeds {seed}.."
          f"{seed + episodes - 1}), {leaks} with cost; {time.perf_counter() - tic:.0f} s, "
          f"{workers} workers")
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
