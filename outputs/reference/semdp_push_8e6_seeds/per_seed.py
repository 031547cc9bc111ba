"""Table 3.1's baselines at 8e6 env steps, per seed and mean ± standard error over seeds 0-2.

    cd outputs/reference/semdp_push_8e6_seeds && python per_seed.py > per_seed.md

Values come from the completed runs kept in ``runs/``, reduced as ``semdp-report`` does: the
final evaluation's ``eval.return_mean`` / ``eval.cost_mean`` (50 episodes), and the training
episodes' ``ep_return`` / ``ep_cost`` averaged over the last 10 % of the epochs. Seed 0's first
run directories were lost with a machine: where no seed-0 run is kept, its value comes from the
table of ``semdp_push_8e6`` (every baseline cell there has one seed, so each entry is seed 0's
value, rounded to 2 decimals). The standard error uses the sample deviation.
"""

from __future__ import annotations

import csv
import json
import re
import statistics
from pathlib import Path

HERE = Path(__file__).resolve().parent
SEED0_TABLE = HERE.parent / "semdp_push_8e6" / "table.md"
METHODS = {"cpo": "CPO", "ppo_lag": "PPO-Lag", "trpo_lag": "TRPO-Lag"}
ENVS = {"point": "PointPush1", "car": "CarPush1", "mass": "MassPush1"}
SECTIONS = {"eval": "Final evaluation (50 episodes)",
            "late": "Training episodes, last 10 % of the epochs"}
Key = tuple[str, str, str, str]  # section, env, metric, method


def seed0_values() -> dict[Key, float]:
    """The baseline cells of ``semdp_push_8e6/table.md`` (seed 0 only)."""
    values: dict[Key, float] = {}
    section, header = "", []
    for line in SEED0_TABLE.read_text().splitlines():
        if line.startswith("Final evaluation"):
            section = "eval"
        elif line.startswith("## Training episodes"):
            section = "late"
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| env"):
            header = [h.replace("PPO Lag", "PPO-Lag").replace("TRPO Lag", "TRPO-Lag")
                      for h in cells]
        elif section and line.startswith("| ") and "---" not in line:
            for method, cell in zip(header[2:], cells[2:], strict=True):
                if method in METHODS.values():
                    values[(section, cells[0], cells[1], method)] = float(cell.split()[0])
    return values


def kept_values() -> dict[Key, dict[int, float]]:
    """Per-seed values of the completed runs in ``runs/push8e6_s<seed>_<method>_<robot>``."""
    values: dict[Key, dict[int, float]] = {}
    for path in sorted((HERE / "runs").glob("push8e6_s*/**/metrics.json")):
        sweep = path.relative_to(HERE / "runs").parts[0]
        seed, method, robot = re.fullmatch(r"push8e6_s(\d+)_(.+)_(\w+?)", sweep).groups()
        metrics = json.loads(path.read_text())
        if metrics.get("status") != "completed":
            continue
        env, label = ENVS[robot], METHODS[method]
        rows = list(csv.DictReader((path.parent / "progress.csv").open()))
        late = rows[-max(1, round(0.1 * len(rows))):]
        for metric, eval_key, column in (("reward", "return_mean", "ep_return"),
                                         ("cost", "cost_mean", "ep_cost")):
            values.setdefault(("eval", env, metric, label), {})[int(seed)] = float(
                metrics["eval"][eval_key])
            xs = [float(r[column]) for r in late if r[column] not in ("", "nan")]
            values.setdefault(("late", env, metric, label), {})[int(seed)] = sum(xs) / len(xs)
    return values


def main() -> None:
    values = kept_values()
    for key, value in seed0_values().items():
        values.setdefault(key, {}).setdefault(0, value)
    seeds = sorted({s for per in values.values() for s in per})
    print("# Table 3.1 baselines at 8e6 env steps: per seed\n")
    print(__doc__.split("\n\n", 2)[2].strip() + "\n")
    for section, title in SECTIONS.items():
        print(f"## {title}\n")
        print("| env | metric | method | " + " | ".join(f"seed {s}" for s in seeds)
              + " | mean ± SE (n) |")
        print("|---|---|---|" + "---|" * (len(seeds) + 1))
        for env in ENVS.values():
            for metric in ("reward", "cost"):
                for method in METHODS.values():
                    per = values.get((section, env, metric, method), {})
                    xs = list(per.values())
                    se = (f"{statistics.stdev(xs) / len(xs) ** 0.5:.2f}" if len(xs) > 1
                          else "–")
                    mean = f"{statistics.mean(xs):.2f}" if xs else "–"
                    print(f"| {env} | {metric} | {method} | "
                          + " | ".join(f"{per[s]:.2f}" if s in per else "–" for s in seeds)
                          + f" | {mean} ± {se} ({len(xs)}) |")
        print()


if __name__ == "__main__":
    main()
