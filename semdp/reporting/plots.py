"""Training curves (Figs. 2.2, 3.3) and the ε' trade-off scatter (Fig. B.1) of a sweep."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.signal import savgol_filter

from semdp.reporting.runs import FloatArray, RunRecord, mean_and_standard_error, pretrain_steps

#: Savitzky-Golay window for long series; shorter series use an adapted odd window.
DEFAULT_WINDOW = 21
POLYORDER = 2
GRID_POINTS = 200


def smooth(
    values: FloatArray, window: int = DEFAULT_WINDOW, polyorder: int = POLYORDER
) -> FloatArray:
    """Savitzky-Golay smoothing with a window adapted to short series.

    The window is the largest odd number ``<= min(window, max(polyorder + 3, len(values) // 3))``
    (a window as long as the series would fit one parabola to a whole 15-epoch run); series
    shorter than ``polyorder + 2`` points are returned unchanged. The result is clipped to the
    range of ``values``, so a cost curve of non-negative values never dips below zero.
    """
    values = np.asarray(values, dtype=np.float64)
    size = min(window, values.size, max(polyorder + 3, values.size // 3))
    if size % 2 == 0:
        size -= 1
    if size < polyorder + 2:
        return values.copy()  # never hand back the caller's array
    smoothed = savgol_filter(values, size, polyorder, mode="interp")
    return np.clip(smoothed, values.min(), values.max())


def _series(run: RunRecord, column: str) -> tuple[FloatArray, FloatArray] | None:
    steps, values = run.curves.get("env_steps"), run.curves.get(column)
    if steps is None or values is None:
        return None
    keep = np.isfinite(steps) & np.isfinite(values)
    if not keep.any():
        return None
    order = np.argsort(steps[keep], kind="stable")
    return steps[keep][order], values[keep][order]


def aggregate_curves(
    series: list[tuple[FloatArray, FloatArray]], points: int = GRID_POINTS
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Smooth each seed, interpolate onto a common step grid, return (grid, mean, standard error).

    The grid spans the smallest to the largest step of any seed; at each grid point only the
    seeds whose series cover it count (an unfinished seed stops contributing where it stopped).
    The standard error is 0 where a single seed covers the point.

    Raises:
        ValueError: when ``series`` is empty.
    """
    if not series:
        raise ValueError("aggregate_curves needs at least one series")
    low = min(float(steps[0]) for steps, _ in series)
    high = max(float(steps[-1]) for steps, _ in series)
    grid = np.linspace(low, high, points) if high > low else np.array([low])
    stacked = np.full((len(series), grid.size), np.nan)
    for row, (steps, values) in enumerate(series):
        smoothed = smooth(values)
        inside = (grid >= steps[0]) & (grid <= steps[-1])
        stacked[row, inside] = np.interp(grid[inside], steps, smoothed)
    finite = np.isfinite(stacked)
    counts = finite.sum(axis=0)
    mean = np.where(finite, stacked, 0.0).sum(axis=0) / np.maximum(counts, 1)
    deviation = np.where(finite, stacked - mean, 0.0)
    variance = (deviation**2).sum(axis=0) / np.maximum(counts - 1, 1)
    error = np.where(counts > 1, np.sqrt(variance / np.maximum(counts, 1)), 0.0)
    keep = counts > 0
    return grid[keep], mean[keep], error[keep]


def method_colours(runs: list[RunRecord]) -> dict[str, str]:
    """One matplotlib colour per method label, shared by every figure of a report."""
    return {label: f"C{index % 10}" for index, label in enumerate(sorted({r.label for r in runs}))}


def pretrain_offset(run: RunRecord) -> int:
    """The run's ``env.pretrain_steps`` (its curves were shifted by them when loaded)."""
    return pretrain_steps(run.path)


def shared_cost_limit(runs: list[RunRecord]) -> float | None:
    """The cost limit all constrained ``runs`` were trained with, or ``None`` if it is unknown
    for some run, differs between them, or no run is constrained (then no line is drawn).
    Unconstrained runs (SAC's "Ours", PPO) have no limit of their own and do not count."""
    limits = {run.cost_limit for run in runs if not run.unconstrained}
    if len(limits) != 1:
        return None
    return limits.pop()


def plot_training_curves(
    runs: list[RunRecord], env: str, path: Path, colours: dict[str, str] | None = None
) -> bool:
    """Episode return and cost vs env steps per method for ``env``; False if nothing to plot.

    Every run with ``progress.csv`` rows counts except failed ones (a crash may leave a diverged
    tail); unfinished runs contribute the steps they reached.
    """
    colours = colours or method_colours(runs)
    figure = Figure(figsize=(12, 4.5), layout="constrained")
    axes = figure.subplots(1, 2)
    by_label: dict[str, list[RunRecord]] = defaultdict(list)
    for run in runs:
        if run.env == env and run.status != "failed":
            by_label[run.label].append(run)
    drawn = False
    for label, group in sorted(by_label.items()):
        colour = colours.get(label, "black")
        for axis, column in zip(axes, ("ep_return", "ep_cost"), strict=True):
            series = [s for s in (_series(run, column) for run in group) if s is not None]
            if not series:
                continue
            grid, mean, error = aggregate_curves(series)
            axis.plot(grid, mean, color=colour, label=_legend(label, len(series)))
            axis.fill_between(grid, mean - error, mean + error, color=colour, alpha=0.25)
            drawn = True
    if not drawn:
        return False
    limit = shared_cost_limit([run for group in by_label.values() for run in group])
    if limit is not None:
        axes[1].axhline(limit, color="grey", linestyle="--", linewidth=1,
                        label=f"cost limit {limit:g}")
    for axis, title in zip(axes, ("episode return", "episode cost"), strict=True):
        axis.set(xlabel="environment steps", ylabel=title, title=f"{env}: {title}")
        axis.legend(fontsize=8)
    offset = any(run.curves.get("env_steps") is not None and len(run.curves["env_steps"])
                 and pretrain_offset(run) for group in by_label.values() for run in group)
    figure.suptitle(f"{env}: mean over seeds, Savitzky-Golay smoothed, shaded = ±1 standard error"
                    + ("; SEMDP curves start after the follower's training steps" if offset
                       else ""))
    figure.savefig(path, dpi=110)
    return True


def plot_tradeoff(
    runs: list[RunRecord], env: str, path: Path, colours: dict[str, str] | None = None
) -> bool:
    """Fig. B.1: reward vs cost, one point per ε' for runs with ``tradeoff``; baselines as points.

    Returns False (and writes nothing) when no run of ``env`` carries trade-off points.
    """
    env_runs = [run for run in runs if run.env == env]
    with_tradeoff = [run for run in env_runs if run.tradeoff]
    if not with_tradeoff:
        return False
    colours = colours or method_colours(runs)
    figure = Figure(figsize=(7, 5.5), layout="constrained")
    axis = figure.subplots()
    ours_labels = sorted({run.label for run in with_tradeoff})
    for label in ours_labels:
        per_clearance: dict[float, list[tuple[float, float]]] = defaultdict(list)
        for run in with_tradeoff:
            if run.label == label:
                for point in run.tradeoff:
                    per_clearance[point.clearance].append((point.cost_mean, point.return_mean))
        clearances = sorted(per_clearance)
        costs, returns = [], []
        for clearance in clearances:
            cost, cost_se = mean_and_standard_error([c for c, _ in per_clearance[clearance]])
            ret, ret_se = mean_and_standard_error([r for _, r in per_clearance[clearance]])
            costs.append(cost)
            returns.append(ret)
            axis.errorbar(
                cost,
                ret,
                xerr=_finite(cost_se),
                yerr=_finite(ret_se),
                fmt="o",
                color=colours.get(label, "black"),
                capsize=3,
            )
            axis.annotate(
                f"ε'={clearance:g}",
                (cost, ret),
                textcoords="offset points",
                xytext=(5, 5),
                fontsize=8,
            )
        axis.plot(costs, returns, color=colours.get(label, "black"), alpha=0.5, label=label)
    baselines = sorted({run.label for run in env_runs} - set(ours_labels))
    for label in baselines:
        group = [run for run in env_runs if run.label == label and run.has_final_eval]
        if not group:
            continue
        cost, cost_se = mean_and_standard_error([run.eval_cost for run in group])
        ret, ret_se = mean_and_standard_error([run.eval_return for run in group])
        axis.errorbar(
            cost,
            ret,
            xerr=_finite(cost_se),
            yerr=_finite(ret_se),
            fmt="s",
            color=colours.get(label, "black"),
            capsize=3,
            label=_legend(label, len(group)),
        )
    axis.set(
        xlabel="evaluation cost",
        ylabel="evaluation return",
        title=f"{env}: reward-cost trade-off over the planner clearance ε'",
    )
    axis.legend(fontsize=8)
    figure.savefig(path, dpi=110)
    return True


def _legend(label: str, seeds: int) -> str:
    """A method's legend entry with its number of seeds ("CPO (1 seed)", "Ours (3 seeds)")."""
    return f"{label} ({seeds} seed{'' if seeds == 1 else 's'})"


def _finite(value: float) -> float:
    return 0.0 if math.isnan(value) else value
