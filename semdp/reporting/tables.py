"""Tables and figures of ``semdp-report`` (the app is :mod:`semdp.cli.report`): mean ± standard
error over seeds per method, env and metric, the late-training window, the differences between
two methods, and the curves and trade-off figures (docs/design.md, "The run directory").
"""

from __future__ import annotations

import math
import os
import re
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from semdp.reporting.compare import difference_lines
from semdp.reporting.names import algorithm_name
from semdp.reporting.plots import method_colours, plot_tradeoff, plot_training_curves
from semdp.reporting.runs import UNKNOWN, RunRecord, load_runs, mean_and_standard_error

TABLE_NAME = "table.md"


def format_cell(values: list[float], max_seeds: int, digits: int = 2) -> str:
    """``mean ± SE`` (``–`` for the error of a single seed), with ``(n=k)`` if seeds are missing."""
    if not values:
        return "–"
    mean, error = mean_and_standard_error(values)
    text = f"{mean:.{digits}f} ± " + ("–" if math.isnan(error) else f"{error:.{digits}f}")
    return text if len(values) == max_seeds else f"{text} (n={len(values)})"


def order_labels(labels: set[str], order: list[str] | None = None) -> list[str]:
    """``order`` first (those present; ``ppo_lag`` also names ``PPO-Lag``), then the remaining
    labels alphabetically."""
    wanted = [algorithm_name(label) if label not in labels else label for label in order or []]
    first = [label for label in wanted if label in labels]
    return first + sorted(labels - set(first))


def build_table(
    runs: list[RunRecord],
    root: Path,
    digits: int = 2,
    order: list[str] | None = None,
    compare: tuple[str, str] | None = None,
    late: float = 0.0,
    at: tuple[float, ...] = (),
) -> str:
    """Markdown of Table 3.1 (mean ± SE over seeds) plus the list of incomplete runs.

    Args:
        runs: loaded run directories.
        root: the sweep directory (run paths are shown relative to it).
        digits: decimals in the cells.
        order: method labels to put first, in this order (Table 3.1: SEMDP, CPO, ...).
        compare: two method labels ``(A, B)`` (``ppo_lag`` also names ``PPO-Lag``): adds the
            section of differences A − B.
        late: with ``0 < late <= 1``, a second table (and differences) of the training
            episodes' return and cost averaged over the last ``late`` fraction of each completed
            run's epochs (the stochastic policy, what the thesis' training curves show).
        at: env-step marks: for each, the same table as ``late`` (its fraction, else 10 %) over
            the epochs up to that many env steps, i.e. what a run stopped there would show
            (runs that never reached it are left out).

    Raises:
        ValueError: if a label of ``compare`` names no method of the runs, or a mark is not
            positive.
    """
    usable = [run for run in runs if run.has_final_eval]
    # Runs known only by their directory (no metrics.json, no config.yaml) get no column or row of
    # their own; they are listed with the incomplete runs below.
    named = [run for run in runs if run.has_final_eval or UNKNOWN not in (run.label, run.env)]
    labels = order_labels({run.label for run in named}, order)
    envs = sorted({run.env for run in named})
    if not 0.0 <= late <= 1.0:
        raise ValueError(f"late must be in [0, 1], got {late}")
    bad = [mark for mark in at if not (math.isfinite(mark) and mark > 0)]
    if bad:
        raise ValueError(f"--at: env-step marks must be > 0, got {bad[0]}")
    pair = None
    if compare is not None:
        pair = [name if name in labels else algorithm_name(name) for name in compare]
        missing = [name for name in pair if name not in labels]
        if missing:
            raise ValueError(f"--compare: no method {missing[0]!r} among {labels}")
    values: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    for run in usable:
        values[(run.env, run.label, "reward")].append(float(run.eval_return))  # type: ignore[arg-type]
        values[(run.env, run.label, "cost")].append(float(run.eval_cost))  # type: ignore[arg-type]
    lines = [
        f"# Results: {root}",
        "",
        "Final evaluation (`metrics.json` eval.return_mean / eval.cost_mean), mean ± standard "
        "error over seeds; `(n=k)` marks cells with fewer seeds than the most complete method.",
        "",
        *_value_table(values, envs, labels, digits),
    ]
    if pair is not None:
        lines += difference_lines(values, envs, pair[0], pair[1], digits)
    if late > 0:
        late_values = late_training_values(usable, late)
        lines += [
            f"## Training episodes, last {late:.0%} of the epochs", "",
            "`progress.csv` ep_return / ep_cost (the stochastic policy's training episodes) "
            f"averaged over the last {late:.0%} of each run's epochs, then mean ± standard "
            "error over seeds.", "",
            *_value_table(late_values, envs, labels, digits),
        ]  # fmt: skip
        if pair is not None:
            lines += difference_lines(late_values, envs, pair[0], pair[1], digits,
                                      title="training episodes")
    fraction = late if late > 0 else 0.1
    for mark in at:
        mark_values = late_training_values(usable, fraction, until=mark)
        lines += [
            f"## Training episodes at {mark:g} env steps", "",
            f"What runs stopped at {mark:g} env steps would show: `progress.csv` ep_return / "
            f"ep_cost (the stochastic policy's training episodes) over the last {fraction:.0%} "
            "of the epochs up to that step, then mean ± standard error over seeds; runs that "
            "never reached it are left out.", "",
            *_value_table(mark_values, envs, labels, digits),
        ]  # fmt: skip
        if pair is not None:
            lines += difference_lines(mark_values, envs, pair[0], pair[1], digits,
                                      title=f"training episodes at {mark:g} env steps")
    lines += [f"Runs found: {len(runs)}; with a final evaluation: {len(usable)}.", ""]
    incomplete = [run for run in runs if run.problems]
    if incomplete:
        lines += ["## Failed or unfinished runs", ""]
        for run in incomplete:
            where = run.path.relative_to(root) if run.path.is_relative_to(root) else run.path
            name = f"{run.label} / {run.env}" + (
                f" / seed {run.seed}" if run.seed is not None else ""
            )
            detail = "; ".join(run.problems)
            if run.error:
                detail += f"; error: {run.error}"
            lines.append(f"- `{where}` ({name}): {detail}")
        lines.append("")
    return "\n".join(lines)


def parse_compare(text: str) -> tuple[str, str] | None:
    """``"A,B"`` -> ``("A", "B")``; empty -> ``None``.

    Raises:
        ValueError: for anything but two non-empty labels.
    """
    if not text.strip():
        return None
    parts = [part.strip() for part in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise ValueError(f"--compare takes two method labels A,B, got {text!r}")
    return parts[0], parts[1]


def parse_marks(text: str) -> tuple[float, ...]:
    """``"150000,1e6"`` -> ``(150000.0, 1000000.0)``; empty -> ``()``.

    Raises:
        ValueError: for a mark that is not a number.
    """
    marks = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        try:
            marks.append(float(part))
        except ValueError:
            raise ValueError(f"--at takes env-step numbers like 150000,1e6, got {part!r}") from None
    return tuple(marks)


def _value_table(
    values: dict[tuple[str, str, str], list[float]], envs: list[str], labels: list[str],
    digits: int,
) -> list[str]:
    """Rows env x {reward, cost}, columns methods, cells mean ± SE."""
    lines = ["| env | metric | " + " | ".join(labels) + " |", "|---|---|" + "---|" * len(labels)]
    for env in envs:
        max_seeds = max((len(values[(env, label, "reward")]) for label in labels), default=0)
        for metric in ("reward", "cost"):
            cells = [
                format_cell(values[(env, label, metric)], max_seeds, digits) for label in labels
            ]
            lines.append(f"| {env} | {metric} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def late_training_values(
    runs: list[RunRecord], fraction: float, until: float | None = None
) -> dict[tuple[str, str, str], list[float]]:
    """Per (env, label, metric) the runs' mean training-episode return/cost over the last
    ``fraction`` of their epochs (at least one; empty cells skipped; runs without a training
    episode there are left out). ``until``: only the epochs up to that many env steps (the
    curves' ``env_steps``), as if the run had stopped there; runs that never reached it are
    left out."""
    out: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    for run in runs:
        keep = None
        if until is not None:
            steps = run.curves.get("env_steps")
            if steps is None or steps.size == 0 or float(np.nanmax(steps)) < until:
                continue
            keep = steps <= until
        for metric, column in (("reward", "ep_return"), ("cost", "ep_cost")):
            series = run.curves.get(column)
            if series is None or series.size == 0:
                continue
            if keep is not None:
                series = series[keep[: series.size]]
                if series.size == 0:
                    continue
            tail = series[-max(1, math.ceil(fraction * series.size)):]
            tail = tail[~np.isnan(tail)]
            if tail.size:
                out[(run.env, run.label, metric)].append(float(tail.mean()))
    return out


def _file_safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "env"


def write_report(
    root: Path | Sequence[Path],
    out_dir: Path,
    digits: int = 2,
    order: list[str] | None = None,
    compare: tuple[str, str] | None = None,
    late: float = 0.0,
    at: tuple[float, ...] = (),
) -> list[Path]:
    """Write ``table.md``, the curve PNGs and any trade-off PNGs; return the written paths.

    ``root``: a sweep directory, or several (e.g. one sweep per seed, or sweeps of several
    sessions): their runs are reported together, each run once.

    Raises:
        ValueError: if a root is not a directory or none holds a run directory.
    """
    roots = [Path(r).resolve() for r in ([root] if isinstance(root, str | Path) else root)]
    if not roots:
        raise ValueError("no sweep directory given")
    out_dir = Path(out_dir).resolve()
    runs, seen = [], set()
    for sweep in roots:
        # Runs below the output folder are skipped unless their sweep was asked for by name
        # (a reference folder's kept runs, semdp.experiments.archive).
        asked_inside = sweep.is_relative_to(out_dir)
        for run in load_runs(sweep):
            if run.path not in seen and (asked_inside or not run.path.is_relative_to(out_dir)):
                seen.add(run.path)
                runs.append(run)
    root = roots[0] if len(roots) == 1 else Path(os.path.commonpath(roots))
    if not runs:
        raise ValueError("no run directories (metrics.json or progress.csv) found below "
                         + ", ".join(map(str, roots)))
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / TABLE_NAME]
    written[0].write_text(build_table(runs, root, digits, order, compare, late, at))
    colours = method_colours(runs)
    for env in sorted({run.env for run in runs}):
        curves = out_dir / f"curves_{_file_safe(env)}.png"
        if plot_training_curves(runs, env, curves, colours):
            written.append(curves)
        tradeoff = out_dir / f"tradeoff_{_file_safe(env)}.png"
        if plot_tradeoff(runs, env, tradeoff, colours):
            written.append(tradeoff)
    return written
