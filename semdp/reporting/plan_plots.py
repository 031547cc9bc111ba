"""The figures of ``semdp-plan``: one plan with its certificate, or several planners' plans of
one problem overlaid (thesis §3.5.2; docs/planner.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from solvers.planner import Comparison, PlanResult

_STYLES = ("-", "--", "-.", ":")
_MARKERS = ("o", "s", "^", "D", "v", "P", "X")


def _axes(size: tuple[float, float] = (6.4, 6.0)) -> tuple[Any, Any]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(figsize=size)


def _draw_obstacles(ax: Any, obstacles: np.ndarray, clearances: list[float]) -> None:
    """Obstacle discs (radius filled), their eps' + r circles (dashed) and centres."""
    from matplotlib.patches import Circle

    for row in obstacles:
        radius = float(row[2]) if len(row) > 2 else 0.0
        if radius > 0:
            ax.add_patch(Circle(row[:2], radius, color="tab:purple", alpha=0.6))
        for clearance in clearances:
            ax.add_patch(Circle(row[:2], clearance + radius, fill=False, ls="--",
                                color="tab:purple"))
        ax.plot(row[0], row[1], "x", color="tab:purple")


def _finish(ax: Any, fig: Any, points: np.ndarray, obstacles: np.ndarray, clearance: float,
            path: Path) -> None:
    everything = np.vstack([points, *(o[None, :2] for o in obstacles)])
    low = everything.min(axis=0) - clearance - 0.5
    high = everything.max(axis=0) + clearance + 0.5
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    import matplotlib.pyplot as plt

    plt.close(fig)


def plot_plan(
    result: PlanResult,
    subgoal: np.ndarray,
    obstacles: np.ndarray,
    clearance: float,
    path: Path,
) -> None:
    """Draw obstacles (radius filled, eps' + r dashed), waypoints, start, subgoal, certificate."""
    fig, ax = _axes()
    _draw_obstacles(ax, obstacles, [clearance])
    points = result.waypoints
    ax.plot(points[:, 0], points[:, 1], "-o", ms=3, color="tab:green", label="waypoints")
    ax.plot(*points[0], "o", ms=9, color="tab:red", label="start")
    ax.plot(*subgoal, "*", ms=14, color="tab:orange", label="subgoal")
    text = (
        f"{result.backend}: {result.status}\n"
        f"feasible={result.feasible} fallback={result.fallback} escape={result.escape_mode}\n"
        f"min clearance: waypoints {result.min_clearance:.4f} m, "
        f"continuous {result.min_clearance_continuous:.4f} m (eps'={clearance})\n"
        f"||x_N - g||={np.sqrt(result.objective):.4f} m, {result.solve_time_s * 1e3:.1f} ms"
    )
    ax.text(0.01, 0.99, text, transform=ax.transAxes, va="top", fontsize=8,
            bbox={"facecolor": "white", "alpha": 0.85})
    ax.legend(loc="lower right", fontsize=8)
    _finish(ax, fig, np.vstack([points, subgoal[None, :]]), obstacles, clearance, path)


def plot_comparison(comparison: Comparison, path: Path) -> None:
    """Every planner's plan of one problem overlaid, with the obstacles' eps' + r circles and a
    legend giving each planner's time (ms), its smallest clearance, its smoothness against the
    budget (Eq. 3.3) and a fallback."""
    import matplotlib.pyplot as plt

    fig, ax = _axes((7.2, 6.4))
    clearances = sorted({row.clearance for row in comparison.rows})
    _draw_obstacles(ax, comparison.obstacles, clearances)
    colours = plt.get_cmap("tab10").colors
    for k, row in enumerate(comparison.rows):
        points = row.result.waypoints
        clearance = (f"min clearance {row.min_clearance:.3f} m"
                     if np.isfinite(row.min_clearance) else "no obstacles")
        flags = (", FALLBACK" if row.fallback
                 else "" if row.reached_subgoal else ", subgoal not reached")
        if not row.within_budget:
            flags += f", h_smooth {row.smoothness / row.smoothness_budget:.1f}x budget"
        ax.plot(points[:, 0], points[:, 1], ls=_STYLES[k % len(_STYLES)],
                marker=_MARKERS[k % len(_MARKERS)], ms=3.5, lw=1.6, alpha=0.85,
                color=colours[k % len(colours)],
                label=f"{row.name}: {row.ms:.2f} ms, {clearance}{flags}")
    ax.plot(*comparison.start, "o", ms=9, color="tab:red", label="start", zorder=5)
    ax.plot(*comparison.subgoal, "*", ms=15, color="tab:orange", label="subgoal", zorder=5)
    eps = ", ".join(f"{c:g}" for c in clearances)
    ax.set_title(f"{len(comparison.rows)} planners, one problem (dashed: eps' + r, eps' = {eps} m)",
                 fontsize=10)
    ax.legend(loc="best", fontsize=8, framealpha=0.9)
    points = np.vstack([*(row.result.waypoints for row in comparison.rows),
                        comparison.subgoal[None, :]])
    _finish(ax, fig, points, comparison.obstacles, max(clearances), path)
