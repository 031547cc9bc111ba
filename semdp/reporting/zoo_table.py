"""The policy zoo's table: every committed policy's ``semdp-eval`` result (its ``eval.json``), one
row per entry, then mean ± standard error per env over the entries' seeds.

    python -m semdp.reporting.zoo_table [--out outputs/reference/zoo.md]

Rebuilt from committed files only (``outputs/reference/zoo.yaml`` and each entry's
``eval.json``; the protocol: 50 single-env episodes, mean action, evaluation seeds 10000-10049
plus the run's seed, cost limit 0 where the method has one). ``semdp-eval zoo:<name>``
reproduces an entry's row (tests/test_zoo.py checks recorded episodes).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import yaml

from semdp.evaluation.zoo import INDEX, entries
from semdp.reporting.names import env_name, trained_env
from semdp.reporting.tables import format_cell

TITLE = "# Policy zoo: semdp-eval of every committed policy"


def _env(run_dir: Path, recorded: str) -> str:
    """The task the policy was trained on: from its config's gymnasium id where it has one
    (``env=semdp_point_push1 env.task=Button1`` is PointButton1), else the recorded env name."""
    config = run_dir / "config.yaml"
    if config.is_file():
        env_id = (yaml.safe_load(config.read_text()).get("env") or {}).get("id", "")
        return trained_env(str(env_id), recorded)
    return env_name(recorded)


def entry_rows(index: Path = INDEX) -> list[dict[str, object]]:
    """One dict per zoo entry: name, env, seed, env steps and its ``eval.json`` summary."""
    rows = []
    for name, run_dir in sorted(entries(index).items()):
        recorded = json.loads((run_dir / "eval.json").read_text())
        summary = recorded["eval"]
        rows.append({
            "name": name, "method": recorded.get("label", "").split(" [eval")[0],
            "env": _env(run_dir, str(recorded["env"])), "seed": recorded["seed"],
            "env_steps": recorded["env_steps"], "return": summary["return_mean"],
            "return_std": summary["return_std"], "cost": summary["cost_mean"],
            "episodes": summary["episodes"], "with_cost": summary.get("episodes_with_cost"),
            "fallbacks": summary.get("plan_fallbacks"), "plans": summary.get("plans"),
        })
    return rows


def zoo_table(rows: Sequence[dict[str, object]]) -> str:
    """The markdown table: per entry, then per method, env and training steps mean ± SE over
    its entries (policies trained for other budgets are not averaged together)."""
    lines = [TITLE, "", "Built by `python -m semdp.reporting.zoo_table` from `zoo.yaml` and each "
             "entry's `eval.json`: 50 single-env episodes, mean action, evaluation seeds "
             "10000-10049 + the run's seed. Training steps are the run's `env_steps` "
             "(high-level steps for a SEMDP run: 10 env steps each).", "",
             "| entry | method | env | seed | training steps | return (± std) | cost | episodes "
             "with cost | fallback plans |", "|---|---|---|---|---|---|---|---|---|"]
    by_env: dict[tuple[str, str, int], list[dict[str, object]]] = defaultdict(list)
    for row in rows:
        by_env[(str(row["method"]), str(row["env"]), int(row["env_steps"]))].append(row)  # type: ignore[call-overload]
        fallbacks = "–" if row["fallbacks"] is None else f"{row['fallbacks']} / {row['plans']}"
        lines.append(f"| `{row['name']}` | {row['method']} | {row['env']} | {row['seed']} | "
                     f"{row['env_steps']:,} "
                     f"| {row['return']:.3f} ± {row['return_std']:.3f} | {row['cost']:.3f} | "
                     f"{row['with_cost']} / {row['episodes']} | {fallbacks} |")
    lines += ["", "| method | env | training steps | entries | return, mean ± SE over seeds "
              "| cost, mean ± SE |", "|---|---|---|---|---|---|"]
    for (method, env, steps), group in sorted(by_env.items()):
        returns = [float(r["return"]) for r in group]  # type: ignore[arg-type]
        costs = [float(r["cost"]) for r in group]  # type: ignore[arg-type]
        lines.append(f"| {method} | {env} | {steps:,} | {len(group)} | "
                     f"{format_cell(returns, len(group))} | {format_cell(costs, len(group))} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    """Print the table, or write it with ``--out``."""
    parser = argparse.ArgumentParser(prog="python -m semdp.reporting.zoo_table",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None, help="write the table here")
    parser.add_argument("--index", type=Path, default=INDEX, help="the zoo's index")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    text = zoo_table(entry_rows(args.index))
    if args.out is None:
        print(text, end="")
    else:
        args.out.write_text(text)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
