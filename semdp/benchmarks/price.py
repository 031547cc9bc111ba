"""``semdp-bench price``: what the safety layer costs in reward, one factor at a time.

The thesis claims high reward *and* zero cost for the Safety-Embedded MDP (§3.5, Table 3.1).
This project's SEMDP adds a low-level safety filter beyond the thesis (``env.shield``:
LiDAR-bounded cost regions, wrong buttons, gremlin reach sets, escapes) and plans from the
robot's LiDAR. Each committed policy is evaluated as ``semdp-eval`` does (the thesis' protocol:
mean action, 50 episodes, eps' = 0.5) and then with **one factor changed**, so the reward each
part of the safety layer takes is measured on the same policies and episode seeds:

========================  ==================================================================
factor                    what changes (``semdp-eval`` arguments)
========================  ==================================================================
``configured``            nothing: the zoo's protocol (reproduces each entry's ``eval.json``)
``planner_gt``            the planner sees the true obstacles (``perception=gt``, "w/ gt")
``filter_gt``             the filter's regions from the true obstacles, not LiDAR-bounded
``filter_unbounded``      the filter reads LiDAR as the planner does (no bearing-error bound)
``filter_bin``            the filter bounds a LiDAR object's bearing by its whole bin
``filter_aliasing``       the filter bounds it by the neighbour bins' aliasing (exact for an
                          isolated object; semdp/embedded/shield.py)
``no_filter``             no low-level filter (the thesis' plain follower; cost allowed here:
                          it measures the price, it is not a mode to ship)
``gt_all``                planner and filter both from the true obstacles
``sampled``               the stochastic policy's sampled actions instead of its mean
``clearance_0.3``         the planner's eps' 0.3 m instead of the configured (= thesis) 0.5 m
``lookahead_0.2``         the follower's tracking point 0.2 m ahead (the thesis', App. B.2.2)
``lookahead_0.4``         ... 0.4 m ahead (the Point's configured look-ahead, conf/robot/)
``planner_no_gremlins``   the planner ignores the gremlins; the filter still keeps the robot out
                          of their orbit discs (the room the planner's discs take)
``moving_gremlins``       the planner sees each gremlin where it is, the filter certifies plans
                          against where the gremlin law puts it (``env.gremlins=moving``)
``no_gremlins``           planner and filter ignore the gremlins (cost allowed: the room the
                          orbit discs take, the ceiling of any finer gremlin model)
========================  ==================================================================

    semdp-bench price                                   # Push1's 9 zoo policies x every factor
    semdp-bench price set=button1 workers=2             # Button1's 9 zoo policies
    semdp-bench price runs=[zoo:semdp_car_push1_s1] factors=[configured,no_filter] episodes=10

``set=`` names sets of policies (``push1``, the default when no ``runs=`` are given;
``button1``; ``button1_whole_bin``, the archived Button1 runs), ``runs=`` adds run
directories or ``zoo:<name>`` entries.

Per policy and factor it records reward, cost, episodes with cost and every intervention rate
(filter %: low-level commands the filter replaced; filter escape %: of those by an escape
action rather than braking; plan escape, fallback and rescue %: of the high-level steps).
Rows are appended to ``price.csv`` under ``out=`` as each cell finishes, so a run cut short is
continued by the same command with the same ``out=`` (finished cells are skipped); a command
with other factors or policies adds its rows to the same table, and ``commands.txt`` lists
every command that wrote to it.
``price.md`` then holds, per robot and factor, mean ± standard error over the policies (seeds)
and the paired difference to ``configured``; ``price.png`` draws those differences.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import os
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from semdp.benchmarks.arguments import BenchArgumentError, as_choices, as_int, as_list, parse_args
from semdp.embedded.perception import OBSTACLE_KINDS
from semdp.paths import REPO_ROOT

#: The obstacle kinds less the gremlins (``semdp-eval`` list syntax).
_NO_GREMLINS = "[" + ",".join(k for k in OBSTACLE_KINDS if k != "gremlins") + "]"
#: Factor name -> (``semdp-eval`` arguments, what it changes).
FACTORS: dict[str, tuple[tuple[str, ...], str]] = {
    "configured": ((), "as configured: the zoo's protocol"),
    "planner_gt": (("perception=gt",), "planner from true obstacles"),
    "filter_gt": (("env.eval_wrapper.shield.perception=gt",), "filter from true obstacles"),
    "filter_unbounded": (("env.eval_wrapper.shield.lidar_bearing_bound=none",),
                         "filter without the LiDAR bearing bound"),
    "filter_bin": (("env.eval_wrapper.shield.lidar_bearing_bound=bin",),
                   "filter's LiDAR bearing bounded by the whole bin"),
    "filter_aliasing": (("env.eval_wrapper.shield.lidar_bearing_bound=aliasing",),
                        "filter's LiDAR bearing bounded by the neighbour bins' aliasing"),
    "no_filter": (("env.eval_wrapper.shield=null",), "no low-level filter"),
    "gt_all": (("perception=gt", "env.eval_wrapper.shield.perception=gt"),
               "planner and filter from true obstacles"),
    "sampled": (("actions=sampled",), "sampled instead of mean actions"),
    "clearance_0.3": (("clearance=0.3",), "planner eps' 0.3 m instead of 0.5 m"),
    "lookahead_0.2": (("env.eval_wrapper.d_min=0.2",), "tracking point 0.2 m ahead (thesis)"),
    "lookahead_0.4": (("env.eval_wrapper.d_min=0.4",), "tracking point 0.4 m ahead"),
    "planner_no_gremlins": ((f"+env.eval_wrapper.obstacle_kinds={_NO_GREMLINS}",),
                            "planner ignores the gremlins (the filter still avoids them)"),
    "moving_gremlins": (("+env.eval_wrapper.gremlins=moving",
                         "+env.eval_wrapper.shield.gremlins=moving"),
                        "gremlins where the law puts them, not their orbit discs"),
    "no_gremlins": ((f"+env.eval_wrapper.obstacle_kinds={_NO_GREMLINS}",
                     f"+env.eval_wrapper.shield.kinds={_NO_GREMLINS}"),
                    "planner and filter ignore the gremlins"),
}
ROBOTS = ("point", "car", "mass")
_BUTTON1_WHOLE_BIN = ("outputs/reference/archive/semdp_button1_whole_bin/runs/semdp_collect_v4/"
                      "semdp_{robot}_button1_s{seed}")
#: Named sets of policies: the Push1 and Button1 zoo entries, and the archived Button1 runs
#: trained with the whole-bin bound (a relative path is looked up from the working directory,
#: else from the repository root).
SETS: dict[str, tuple[str, ...]] = {
    "push1": tuple(f"zoo:semdp_{r}_push1_s{s}" for r in ROBOTS for s in range(3)),
    "button1": tuple(f"zoo:semdp_{r}_button1_s{s}" for r in ROBOTS for s in range(3)),
    "button1_whole_bin": tuple(_BUTTON1_WHOLE_BIN.format(robot=r, seed=s)
                               for r in ROBOTS for s in range(3)),
}
#: Columns of ``price.csv`` (one row per policy and factor).
COLUMNS = ("run", "robot", "task", "seed", "factor", "episodes", "return_mean", "return_std",
           "cost_mean", "episodes_with_cost", "shield_rate", "shield_escape_rate",
           "plan_escape_rate", "plan_fallback_rate", "plan_rescue_rate", "wall_s")
#: Rates reported in percent.
RATES = ("shield_rate", "shield_escape_rate", "plan_escape_rate", "plan_fallback_rate",
         "plan_rescue_rate")


@dataclass(frozen=True)
class Cell:
    """One policy under one factor."""

    run: str
    factor: str
    episodes: int


def locate(run: str) -> str:
    """``run`` as :func:`~semdp.evaluation.run.play_run` takes it: a zoo entry or an existing
    path as given, a relative path missing here taken from the repository root."""
    if run.startswith("zoo:") or Path(run).is_absolute() or Path(run).exists():
        return run
    return str(REPO_ROOT / run)


def evaluate_cell(cell: Cell) -> dict[str, Any]:
    """The ``price.csv`` row of ``cell`` (its evaluation episodes played, nothing written)."""
    import torch

    from semdp.evaluation.episodes import summarise
    from semdp.evaluation.run import play_run

    torch.set_num_threads(1)
    arguments = [*FACTORS[cell.factor][0], f"episodes={cell.episodes}"]
    played = play_run(locate(cell.run), arguments)
    ev = summarise(played.episodes)
    cfg = played.cfg
    env_name = str(cfg.get("env_name") or "")
    robot = next((r for r in ROBOTS if f"_{r}_" in f"_{env_name}_"), "?")
    row = {"run": cell.run, "robot": robot, "task": str(cfg.env.get("task", "")),
           "seed": int(cfg.get("seed", 0)), "factor": cell.factor,
           "wall_s": round(played.wall_time_s, 1)}
    row.update({key: ev.get(key) for key in COLUMNS if key not in row})
    return row


def read_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a ``price.csv`` (numbers as floats)."""
    if not path.is_file():
        return []
    with path.open() as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for key in COLUMNS[5:]:
            row[key] = float(row[key]) if row[key] not in ("", "None") else math.nan
        row["seed"] = int(row["seed"])
    return rows


def _append(path: Path, row: dict[str, Any]) -> None:
    new = not path.is_file()
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        if new:
            writer.writeheader()
        writer.writerow(row)
        f.flush()
        os.fsync(f.fileno())


def _mean_se(values: Sequence[float]) -> tuple[float, float]:
    v = np.asarray(values, dtype=np.float64)
    se = float(v.std(ddof=1) / math.sqrt(len(v))) if len(v) > 1 else math.nan
    return float(v.mean()), se


def _pm(mean: float, se: float, digits: int = 2) -> str:
    return f"{mean:.{digits}f} ± {se:.{digits}f}" if math.isfinite(se) else f"{mean:.{digits}f} ± –"


def summary_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per task, robot and factor: means over the policies, and the paired difference of the
    reward to ``configured`` (over the policies that have both)."""
    base = {(r["run"]): r for r in rows if r["factor"] == "configured"}
    out = []
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["robot"], r["factor"]), []).append(r)
    order = {name: i for i, name in enumerate(FACTORS)}
    for (task, robot, factor), group in sorted(
            groups.items(), key=lambda kv: (kv[0][0], ROBOTS.index(kv[0][1])
                                            if kv[0][1] in ROBOTS else 9, order[kv[0][2]])):
        reward = _mean_se([r["return_mean"] for r in group])
        paired = [r["return_mean"] - base[r["run"]]["return_mean"] for r in group
                  if r["run"] in base]
        delta = _mean_se(paired) if paired else (math.nan, math.nan)
        out.append({
            "task": task, "robot": robot, "factor": factor, "policies": len(group),
            "episodes": int(sum(r["episodes"] for r in group)),
            "reward": reward, "delta": delta,
            "cost": float(np.mean([r["cost_mean"] for r in group])),
            "episodes_with_cost": int(sum(r["episodes_with_cost"] for r in group)),
            **{key: 100.0 * float(np.nanmean([r[key] for r in group])) for key in RATES},
        })
    return out


def markdown(rows: list[dict[str, Any]], command: str) -> str:
    """``price.md``: the table of :func:`summary_rows` with the meanings of the factors in it,
    produced by ``command`` (one or several lines)."""
    lines = ["# The price of safety", "", "Produced with:", "", "```bash", command, "```", "",
             "Each committed policy evaluated with one factor changed (the thesis' protocol: mean "
             "action, eps' = 0.5, seeds as `semdp-eval`); reward is the mean over the policies "
             "(seeds) ± standard error, Δ reward the paired difference to `configured` ± its "
             "standard error; cost the mean episode cost; filter % the low-level commands the "
             "filter replaced, filter esc. % those replaced by an escape action; plan esc., "
             "fallback and rescue % of the high-level steps.", "",
             "| factor | what changes |", "|---|---|"]
    used = {row["factor"] for row in rows}
    lines += [f"| `{name}` | {text} |" for name, (_, text) in FACTORS.items() if name in used]
    lines += ["", "| task | robot | factor | policies | reward | Δ reward | cost | episodes with "
              "cost | filter % | filter esc. % | plan esc. % | fallback % | rescue % |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary_rows(rows):
        delta = "–" if s["factor"] == "configured" else _pm(*s["delta"])
        lines.append(
            f"| {s['task']} | {s['robot']} | `{s['factor']}` | {s['policies']} | "
            f"{_pm(*s['reward'])} | {delta} | {s['cost']:.2f} | "
            f"{s['episodes_with_cost']} / {s['episodes']} | " + " | ".join(
                f"{s[key]:.1f}" for key in RATES) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """``price.png``: Δ reward to ``configured`` per factor, one bar per robot, ± SE."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = [s for s in summary_rows(rows) if s["factor"] != "configured"]
    tasks = sorted({s["task"] for s in summary})
    factors = [f for f in FACTORS if f != "configured" and any(s["factor"] == f for s in summary)]
    if not tasks or not factors:
        return
    fig, axes = plt.subplots(1, len(tasks), figsize=(6.5 * len(tasks), 3.8), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        robots = [r for r in ROBOTS if any(s["robot"] == r and s["task"] == task
                                           for s in summary)]
        width = 0.8 / max(len(robots), 1)
        for j, robot in enumerate(robots):
            xs, ys, es = [], [], []
            for i, factor in enumerate(factors):
                s = next((s for s in summary if (s["task"], s["robot"], s["factor"])
                          == (task, robot, factor)), None)
                if s is not None:
                    xs.append(i + (j - (len(robots) - 1) / 2) * width)
                    ys.append(s["delta"][0])
                    es.append(s["delta"][1] if math.isfinite(s["delta"][1]) else 0.0)
            ax.bar(xs, ys, width, yerr=es, capsize=2, label=robot)
        ax.axhline(0.0, color="black", linewidth=0.8)
        ax.set_xticks(range(len(factors)), factors, rotation=30, ha="right")
        ax.set_ylabel("Δ reward vs configured")
        ax.set_title(task)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _runs(args: dict[str, str]) -> list[str]:
    runs = as_list(args["runs"])
    for name in as_list(args["set"]) or ([] if runs else ["push1"]):
        if name not in SETS:
            raise BenchArgumentError(f"semdp-bench price: set must be one of {list(SETS)}, "
                                     f"got {name!r}")
        runs += SETS[name]
    return runs


def main(argv: list[str]) -> None:
    """Evaluate the cells not yet in ``out/price.csv``, then write the table and the figure."""
    stamp = dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    args = parse_args("price", argv, {
        "set": "[]", "runs": "[]", "factors": "[" + ",".join(FACTORS) + "]",
        "episodes": "50", "workers": "1", "out": f"outputs/bench/price_{stamp}"})
    factors = as_choices(args, "factors", list(FACTORS))
    episodes = as_int(args, "episodes", minimum=1)
    workers = as_int(args, "workers", minimum=1)
    runs = _runs(args)
    from semdp.evaluation.errors import EvalError
    from semdp.evaluation.zoo import resolve
    for run in runs:
        try:
            path, _ = resolve(locate(run))
        except EvalError as exc:
            raise BenchArgumentError(f"semdp-bench price: {exc}") from None
        if not path.is_dir():
            raise BenchArgumentError(f"semdp-bench price: {run}: no such run directory")
    out = Path(args["out"])
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / "price.csv"
    done = {(r["run"], r["factor"]) for r in read_rows(csv_path)
            if int(r["episodes"]) == episodes}
    cells = [Cell(run, f, episodes) for run in runs for f in factors if (run, f) not in done]
    print(f"semdp-bench price: {len(runs)} policies x {len(factors)} factors, {episodes} "
          f"episodes each; {len(cells)} cells to run ({len(done)} in {csv_path})", flush=True)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for i, row in enumerate(pool.map(evaluate_cell, cells)):
            _append(csv_path, row)
            print(f"[{i + 1}/{len(cells)}] {row['robot']} {row['task']} s{row['seed']} "
                  f"{row['factor']}: reward {row['return_mean']:.3f}, cost "
                  f"{row['cost_mean']:.3f}, filter {100 * row['shield_rate']:.1f} %, "
                  f"{row['wall_s']:.0f} s", flush=True)
    rows = [r for r in read_rows(csv_path) if int(r["episodes"]) == episodes]
    commands = (out / "commands.txt").read_text().splitlines() if (
        out / "commands.txt").is_file() else []
    command = " ".join(["semdp-bench price", *argv])
    if command not in commands:
        commands.append(command)
        (out / "commands.txt").write_text("\n".join(commands) + "\n")
    table = markdown(rows, "\n".join(commands))
    (out / "price.md").write_text(table)
    plot(rows, out / "price.png")
    print(table)
    print(f"wrote {csv_path}, {out / 'price.md'}, {out / 'price.png'}")


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
