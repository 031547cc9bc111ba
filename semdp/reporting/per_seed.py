"""Per-seed tables: each completed run's value in its seed's column, then mean ± standard error
over the seeds, for the final evaluation and the late training episodes (Table 3.1's cells
seed by seed; :mod:`semdp.reporting.tables` has the means only).

    python -m semdp.reporting.per_seed <sweep dir> [<sweep dir> ...] [--out per_seed.md]
        [--title TEXT] [--order CPO,PPO-Lag,TRPO-Lag] [--late 0.1] [--digits 2]

The values are ``semdp-report``'s (:func:`~semdp.reporting.runs.load_runs`,
:func:`~semdp.reporting.tables.late_training_values`): ``metrics.json``'s
``eval.return_mean`` / ``eval.cost_mean``, and ``progress.csv``'s ``ep_return`` / ``ep_cost``
averaged over the last ``--late`` fraction of each run's epochs. Only runs completed with a
final evaluation and a seed count; rows are env x {reward, cost} x method (methods in
``--order``, then alphabetically; envs alphabetically, as in ``table.md``).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from semdp.reporting.runs import RunRecord, load_runs, mean_and_standard_error
from semdp.reporting.tables import late_training_values, order_labels

#: (section, env, metric, method) -> {seed: value}.
Key = tuple[str, str, str, str]
METRICS = ("reward", "cost")


def per_seed_values(runs: Sequence[RunRecord], late: float) -> dict[Key, dict[int, float]]:
    """Each usable run's final-evaluation (section ``"eval"``) and late-training (``"late"``)
    values by seed.

    Raises:
        ValueError: two usable runs of the same method, env and seed.
    """
    values: dict[Key, dict[int, float]] = {}
    seen: dict[tuple[str, str, int], Path] = {}
    for run in runs:
        if not run.has_final_eval or run.seed is None:
            continue
        cell = (run.label, run.env, run.seed)
        if cell in seen:
            raise ValueError(f"two runs of {run.label} on {run.env} with seed {run.seed}: "
                             f"{seen[cell]} and {run.path}")
        seen[cell] = run.path
        values.setdefault(("eval", run.env, "reward", run.label), {})[run.seed] = float(
            run.eval_return)  # type: ignore[arg-type]
        values.setdefault(("eval", run.env, "cost", run.label), {})[run.seed] = float(
            run.eval_cost)  # type: ignore[arg-type]
        for (env, label, metric), (value,) in late_training_values([run], late).items():
            values.setdefault(("late", env, metric, label), {})[run.seed] = value
    return values


def _number(value: float, digits: int) -> str:
    return "–" if math.isnan(value) else f"{value:.{digits}f}"


def per_seed_table(runs: Sequence[RunRecord], title: str, late: float = 0.1,
                   order: list[str] | None = None, digits: int = 2) -> str:
    """Markdown: the final evaluation's and the late training episodes' table, one column per
    seed and ``mean ± SE (n)`` (module docstring).

    Raises:
        ValueError: ``late`` outside (0, 1], no usable run, or two runs of one cell.
    """
    if not 0.0 < late <= 1.0:
        raise ValueError(f"late must be in (0, 1], got {late}")
    values = per_seed_values(runs, late)
    if not values:
        raise ValueError("no run completed with a final evaluation and a seed")
    seeds = sorted({seed for per in values.values() for seed in per})
    methods = order_labels({key[3] for key in values}, order)
    envs = sorted({key[1] for key in values})
    n_runs = sum(len(per) for key, per in values.items() if key[0] == "eval" and key[2] == "reward")
    sections = {
        "eval": "Final evaluation",
        "late": f"Training episodes, last {late:.0%} of the epochs",
    }
    lines = [
        f"# {title}", "",
        f"{n_runs} runs ({len(methods)} methods x {len(envs)} envs, seeds "
        f"{', '.join(map(str, seeds))}): the final evaluation's "
        "`eval.return_mean` / `eval.cost_mean` and the training episodes' `ep_return` / "
        f"`ep_cost` averaged over the last {late:.0%} of each run's epochs, as `semdp-report` "
        "reduces them; mean ± standard error (sample deviation) over the seeds, (n) seeds.", "",
    ]  # fmt: skip
    for section, heading in sections.items():
        lines += [
            f"## {heading}", "",
            "| env | metric | method | " + " | ".join(f"seed {s}" for s in seeds)
            + " | mean ± SE (n) |",
            "|---|---|---|" + "---|" * (len(seeds) + 1),
        ]  # fmt: skip
        for env in envs:
            for metric in METRICS:
                for method in methods:
                    per = values.get((section, env, metric, method), {})
                    xs = list(per.values())
                    mean, se = mean_and_standard_error(xs) if xs else (math.nan, math.nan)
                    cells = [_number(per[s], digits) if s in per else "–" for s in seeds]
                    lines.append(f"| {env} | {metric} | {method} | " + " | ".join(cells)
                                 + f" | {_number(mean, digits)} ± {_number(se, digits)} "
                                 f"({len(xs)}) |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """CLI entry point."""
    parser = argparse.ArgumentParser(prog="python -m semdp.reporting.per_seed",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep_dir", type=Path, nargs="+",
                        help="sweep or parent directory of run dirs (several: reported together)")
    parser.add_argument("--out", type=Path, default=None, help="write here (default: print)")
    parser.add_argument("--title", default="Per seed", help="the table's heading")
    parser.add_argument("--order", default="", help="comma-separated method labels first")
    parser.add_argument("--late", type=float, default=0.1,
                        help="the last fraction of the epochs of the training-episode table")
    parser.add_argument("--digits", type=int, default=2, help="decimals in table cells")
    args = parser.parse_args(argv)
    order = [label.strip() for label in args.order.split(",") if label.strip()]
    try:
        runs, seen = [], set()
        for sweep in args.sweep_dir:
            for run in load_runs(sweep):
                if run.path.resolve() not in seen:
                    seen.add(run.path.resolve())
                    runs.append(run)
        text = per_seed_table(runs, args.title, args.late, order, args.digits)
    except ValueError as exc:
        sys.exit(f"per_seed: {exc}")
    if args.out is None:
        print(text, end="")
    else:
        args.out.write_text(text)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
