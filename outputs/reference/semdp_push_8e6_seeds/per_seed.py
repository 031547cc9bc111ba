"""Table 3.1's baselines at 8e6 env steps, per seed and mean ± standard error over seeds 0-2.

    cd outputs/reference/semdp_push_8e6_seeds && python per_seed.py > per_seed.md

Values come from the completed runs kept in ``runs/``, reduced by ``semdp-report``'s own code
(``load_runs``, ``late_training_values``): the final evaluation's ``eval.return_mean`` /
``eval.cost_mean`` (50 episodes), and the training episodes' ``ep_return`` / ``ep_cost``
averaged over the last 10 % of the epochs; all 27 runs (3 methods x 3 robots x seeds 0-2) are
kept. The standard error uses the sample deviation.
"""

from __future__ import annotations

import math
from pathlib import Path

from semdp.reporting.runs import load_runs, mean_and_standard_error
from semdp.reporting.tables import late_training_values

HERE = Path(__file__).resolve().parent
METHODS = ("CPO", "PPO-Lag", "TRPO-Lag")
LABELS = {"PPO Lag": "PPO-Lag", "TRPO Lag": "TRPO-Lag"}  # Table 3.1's preset labels
ENVS = ("PointPush1", "CarPush1", "MassPush1")
LATE = 0.1  # the last 10 % of the epochs
SECTIONS = {"eval": "Final evaluation (50 episodes)",
            "late": "Training episodes, last 10 % of the epochs"}
Key = tuple[str, str, str, str]  # section, env, metric, method


def kept_values() -> dict[Key, dict[int, float]]:
    """Per-seed values of the completed runs in ``runs/``, reduced by ``semdp-report``'s code."""
    values: dict[Key, dict[int, float]] = {}
    for run in load_runs(HERE / "runs"):
        if run.status != "completed" or run.seed is None:
            continue
        method = LABELS.get(run.label, run.label)
        values.setdefault(("eval", run.env, "reward", method), {})[run.seed] = float(
            run.eval_return)  # type: ignore[arg-type]
        values.setdefault(("eval", run.env, "cost", method), {})[run.seed] = float(
            run.eval_cost)  # type: ignore[arg-type]
        for (env, _, metric), (value,) in late_training_values([run], LATE).items():
            values.setdefault(("late", env, metric, method), {})[run.seed] = value
    return values


def _fmt(value: float) -> str:
    return "–" if math.isnan(value) else f"{value:.2f}"


def main() -> None:
    values = kept_values()
    seeds = sorted({s for per in values.values() for s in per})
    print("# Table 3.1 baselines at 8e6 env steps: per seed\n")
    print(__doc__.split("\n\n", 2)[2].strip() + "\n")
    for section, title in SECTIONS.items():
        print(f"## {title}\n")
        print("| env | metric | method | " + " | ".join(f"seed {s}" for s in seeds)
              + " | mean ± SE (n) |")
        print("|---|---|---|" + "---|" * (len(seeds) + 1))
        for env in ENVS:
            for metric in ("reward", "cost"):
                for method in METHODS:
                    per = values.get((section, env, metric, method), {})
                    xs = list(per.values())
                    mean, se = mean_and_standard_error(xs) if xs else (math.nan, math.nan)
                    print(f"| {env} | {metric} | {method} | "
                          + " | ".join(f"{per[s]:.2f}" if s in per else "–" for s in seeds)
                          + f" | {_fmt(mean)} ± {_fmt(se)} ({len(xs)}) |")
        print()


if __name__ == "__main__":
    main()
