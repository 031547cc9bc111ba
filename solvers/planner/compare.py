"""Compare planners on one problem: the same start, subgoal and obstacles, solved by each.

The numbers are those of the planner's own certificate (thesis §3.5.2) and of every constraint of
the problem (Eqs. 3.3-3.7): the objective ``||x_N - g||^2`` (Eq. 3.4), the smoothness ``h_smooth``
against its budget ``sigma_smooth`` (Eq. 3.6; the LM backend keeps it only as a penalty, so its
plans may get closer to the subgoal by exceeding it), the smallest clearance at the waypoints and
along the path (Eq. 3.7, exact segment distances), whether the subgoal was reached and whether
the plan fell back to the stationary one (``x_1 = s`` holds by construction, Eq. 3.5). Times are
per ``plan`` call, after one untimed call that builds the compiled solvers this problem needs
(docs/planner.md, "Compare backends on one problem").

Usage::

    from solvers.planner import compare_backends
    comparison = compare_backends(start=[0, 0], subgoal=[2, 1], obstacles=[[1, 0.3]])
    print(comparison.table())
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from solvers.planner.backends import BACKENDS
from solvers.planner.planner import SafeTrajectoryPlanner
from solvers.planner.problem.preparation import validate_obstacles, validate_point
from solvers.planner.problem.settings import ProblemSettings
from solvers.planner.protocol import Planner
from solvers.planner.result import PlanResult

#: Columns of :meth:`Comparison.records` (and of ``semdp-plan``'s CSV), in order.
COLUMNS: tuple[str, ...] = (
    "name", "backend", "ms", "iterations", "objective", "smoothness", "smoothness_budget",
    "within_budget", "min_clearance", "min_clearance_continuous", "reached_subgoal", "fallback",
    "feasible", "escape_mode", "rescued", "clearance", "status",
)


@dataclass(frozen=True)
class ComparisonRow:
    """One planner's plan of the compared problem.

    Attributes:
        name: The planner's label (e.g. a ``conf/planner`` name).
        backend: ``PlanResult.backend``.
        ms: Median wall time of the timed ``plan`` calls (ms).
        iterations: Solver iterations of the returned plan.
        objective: ``||x_N - subgoal||^2``.
        smoothness: ``h_smooth`` of the plan (Eq. 3.6).
        smoothness_budget: ``sigma_smooth`` (Eq. 3.3).
        within_budget: ``h_smooth <= sigma_smooth`` (relative tolerance 1e-6).
        min_clearance: Smallest waypoint distance to an obstacle surface (m; ``inf`` without
            obstacles). Compare it with ``clearance``.
        min_clearance_continuous: The same along the segments between waypoints.
        reached_subgoal: ``||x_N - subgoal|| < goal_tolerance``.
        fallback: The stationary plan was returned.
        feasible: The planner's own certificate holds (waypoints, or segments with
            ``continuous``).
        escape_mode: The start was inside a clearance.
        rescued: The rescue backend's plan was returned.
        clearance: The planner's eps' (m).
        status: The solver status.
        result: The full result.
    """

    name: str
    backend: str
    ms: float
    iterations: int
    objective: float
    smoothness: float
    smoothness_budget: float
    within_budget: bool
    min_clearance: float
    min_clearance_continuous: float
    reached_subgoal: bool
    fallback: bool
    feasible: bool
    escape_mode: bool
    rescued: bool
    clearance: float
    status: str
    result: PlanResult = field(repr=False, compare=False)

    def record(self) -> dict[str, object]:
        """The row as plain values, :data:`COLUMNS` order; a non-finite number becomes None
        (JSON has no infinity)."""
        out: dict[str, object] = {}
        for name in COLUMNS:
            value = getattr(self, name)
            out[name] = None if isinstance(value, float) and not math.isfinite(value) else value
        return out


@dataclass(frozen=True)
class Comparison:
    """The compared problem and one row per planner, in the order given.

    Attributes:
        start: (2,) start.
        subgoal: (2,) subgoal.
        obstacles: (m, 3) obstacles as ``[x, y, radius]``.
        rows: One :class:`ComparisonRow` per planner.
    """

    start: np.ndarray
    subgoal: np.ndarray
    obstacles: np.ndarray
    rows: tuple[ComparisonRow, ...]

    def __getitem__(self, name: str) -> ComparisonRow:
        for row in self.rows:
            if row.name == name:
                return row
        raise KeyError(name)

    def records(self) -> list[dict[str, object]]:
        """The rows as dictionaries (see :meth:`ComparisonRow.record`)."""
        return [row.record() for row in self.rows]

    def to_dict(self) -> dict[str, object]:
        """The problem and the rows as plain values (JSON-ready)."""
        return {
            "start": self.start.tolist(),
            "subgoal": self.subgoal.tolist(),
            "obstacles": self.obstacles.tolist(),
            "rows": self.records(),
        }

    def table(self) -> str:
        """A Markdown table: planner, ms, iterations, objective, smoothness against its budget,
        both clearances, reached, fallback."""
        lines = [
            "| planner | ms | iterations | objective ‖x_N − g‖² | h_smooth / σ "
            "| min clearance waypoints (m) | min clearance path (m) | reached subgoal | fallback |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for row in self.rows:
            budget = (f"{row.smoothness:.3g} / {row.smoothness_budget:.3g}"
                      if math.isfinite(row.smoothness_budget) else "–")
            if not row.within_budget:
                budget += f" (over, ×{row.smoothness / row.smoothness_budget:.2f})"
            lines.append(
                f"| {row.name} | {row.ms:.2f} | {row.iterations} | {row.objective:.3g} | "
                f"{budget} | "
                f"{_metres(row.min_clearance)} | {_metres(row.min_clearance_continuous)} | "
                f"{'yes' if row.reached_subgoal else 'no'} | {'yes' if row.fallback else 'no'} |"
            )
        return "\n".join(lines)


def compare(
    start: Sequence[float] | np.ndarray,
    subgoal: Sequence[float] | np.ndarray,
    obstacles: Sequence[Sequence[float]] | np.ndarray | None = None,
    *,
    planners: Mapping[str, Planner],
    repeats: int = 3,
) -> Comparison:
    """Solve one problem with each planner and return the results side by side.

    Each planner first plans the problem once untimed (building the compiled solvers it needs),
    then ``repeats`` times timed, all with ``warm_start=False``; the row holds the median time
    and the last result.

    Args:
        start: (2,) start.
        subgoal: (2,) subgoal.
        obstacles: (m, 2) centres or (m, 3) ``[x, y, radius]``; None or empty for none.
        planners: Label -> planner (anything satisfying :class:`Planner`).
        repeats: Timed calls per planner.

    Raises:
        ValueError: Malformed start, subgoal or obstacles, no planners, an object that is not a
            planner, or ``repeats < 1``.
    """
    start_arr = validate_point("start", start)
    subgoal_arr = validate_point("subgoal", subgoal)
    centres, radii = validate_obstacles(obstacles)
    table = np.column_stack([centres, radii])
    if not planners:
        raise ValueError("planners must name at least one planner")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")
    rows = []
    for name, planner in planners.items():
        if not isinstance(planner, Planner):
            raise ValueError(f"planner {name!r} has no plan(), n_waypoints and clearance: "
                             f"{planner!r}")
        rows.append(_row(name, planner, start_arr, subgoal_arr, table, repeats))
    return Comparison(start_arr, subgoal_arr, table, tuple(rows))


def compare_backends(
    start: Sequence[float] | np.ndarray,
    subgoal: Sequence[float] | np.ndarray,
    obstacles: Sequence[Sequence[float]] | np.ndarray | None = None,
    *,
    backends: Iterable[str] = BACKENDS,
    repeats: int = 3,
    problem: ProblemSettings | None = None,
    rescue_backend: str | None = None,
) -> Comparison:
    """:func:`compare` with one :class:`SafeTrajectoryPlanner` per backend name (its default
    settings), all with the same ``problem`` (e.g. ``ProblemSettings(continuous=True)``) and
    ``rescue_backend``.

    Raises:
        ValueError: An unknown backend, a bad setting, or what :func:`compare` rejects.
    """
    planners: dict[str, Planner] = {
        name: SafeTrajectoryPlanner(name, problem, rescue_backend)
        for name in backends
    }
    return compare(start, subgoal, obstacles, planners=planners, repeats=repeats)


def _row(
    name: str, planner: Planner, start: np.ndarray, subgoal: np.ndarray, obstacles: np.ndarray,
    repeats: int,
) -> ComparisonRow:
    planner.plan(start, subgoal, obstacles, warm_start=False)  # builds what this problem needs
    times = []
    for _ in range(repeats):
        result = planner.plan(start, subgoal, obstacles, warm_start=False)
        times.append(result.solve_time_s)
    return ComparisonRow(
        name=name,
        backend=result.backend,
        ms=1e3 * statistics.median(times),
        iterations=int(result.iterations),
        objective=float(result.objective),
        smoothness=float(result.smoothness),
        smoothness_budget=float(result.smoothness_budget),
        within_budget=bool(result.within_budget),
        min_clearance=float(result.min_clearance),
        min_clearance_continuous=float(result.min_clearance_continuous),
        reached_subgoal=bool(result.reached_subgoal),
        fallback=bool(result.fallback),
        feasible=bool(result.feasible),
        escape_mode=bool(result.escape_mode),
        rescued=bool(result.rescued),
        clearance=float(planner.clearance),
        status=str(result.status),
        result=result,
    )


def _metres(value: float) -> str:
    return f"{value:.4f}" if math.isfinite(value) else "inf"
