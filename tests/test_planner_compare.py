"""``solvers.planner.compare``: one problem, several planners side by side, on problems whose
answer is known (docs/planner.md, "Compare backends on one problem")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from semdp.embedded.straight import StraightLinePlanner
from solvers.planner import (
    Comparison,
    ProblemSettings,
    SafeTrajectoryPlanner,
    compare,
    compare_backends,
)
from solvers.planner.compare import COLUMNS

EPS = 0.5
BACKENDS = ("ipopt", "lm", "scp")


def test_open_space_every_backend_reaches_the_subgoal() -> None:
    comparison = compare_backends([0.0, 0.0], [2.0, 1.0], [], repeats=1)
    assert [row.name for row in comparison.rows] == list(BACKENDS)
    for row in comparison.rows:
        assert row.reached_subgoal and not row.fallback and row.feasible, row
        assert row.objective < 1e-6
        assert math.isinf(row.min_clearance) and math.isinf(row.min_clearance_continuous)
        assert row.ms > 0 and row.iterations >= 1 and row.clearance == EPS
        record = row.record()
        assert list(record) == list(COLUMNS)
        assert record["min_clearance"] is None and record["min_clearance_continuous"] is None
    assert comparison.obstacles.shape == (0, 3)


@pytest.mark.parametrize("continuous", [False, True])
def test_obstacle_on_the_straight_line_every_certified_plan_keeps_clearance(continuous) -> None:
    comparison = compare_backends([0.0, 0.0], [2.5, 0.0], [[1.2, 0.0]], repeats=1,
                                  problem=ProblemSettings(continuous=continuous))
    for row in comparison.rows:
        assert row.feasible and not row.fallback, row
        assert row.min_clearance >= EPS - 1e-9, row
        if continuous:
            assert row.min_clearance_continuous >= EPS - 1e-9, row
        # it bends around: the straight line would pass through the centre
        assert np.abs(row.result.waypoints[:, 1]).max() > 0.3


def test_straight_line_planner_is_compared_too() -> None:
    planners = {
        "lm": SafeTrajectoryPlanner(backend="lm"),
        "straight": StraightLinePlanner(ProblemSettings(n_waypoints=3)),  # a waypoint at the centre
    }
    comparison = compare([0.0, 0.0], [2.0, 0.0], [[1.0, 0.0, 0.1]], planners=planners, repeats=1)
    straight = comparison["straight"]
    assert straight.backend == "straight" and straight.objective == 0.0
    # the segment passes through the centre: clearance to the surface is -r
    assert straight.min_clearance == pytest.approx(-0.1)
    assert straight.min_clearance_continuous == pytest.approx(-0.1)
    assert not straight.feasible
    assert comparison["lm"].min_clearance >= EPS - 1e-9
    assert "| straight |" in comparison.table() and "| lm |" in comparison.table()


def test_compare_gives_the_plans_plan_gives() -> None:
    problem = {"start": [0.3, -0.2], "subgoal": [1.8, 1.4], "obstacles": [[1.0, 0.6], [0.2, 1.0]]}
    planners = {name: SafeTrajectoryPlanner(backend=name) for name in ("ipopt", "lm")}
    comparison = compare(**problem, planners=planners)
    for name in planners:
        alone = SafeTrajectoryPlanner(backend=name).plan(**problem, warm_start=False)
        np.testing.assert_array_equal(comparison[name].result.waypoints, alone.waypoints)
        assert comparison[name].objective == alone.objective


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"obstacles": [[1.0, 0.3], [0.4]]}, "obstacles must be"),
        ({"obstacles": [[1.0, 0.3, -0.1]]}, "radii must be >= 0"),
        ({"subgoal": [1.0, float("nan")]}, "subgoal must be finite"),
        ({"planners": {}}, "at least one planner"),
        ({"planners": {"x": object()}}, "planner 'x' has no plan"),
        ({"repeats": 0}, "repeats must be"),
    ],
)
def test_compare_rejects_bad_input(kwargs, match) -> None:
    args = {"start": [0.0, 0.0], "subgoal": [1.0, 1.0], "obstacles": None,
            "planners": {"lm": SafeTrajectoryPlanner(backend="lm")}} | kwargs
    with pytest.raises(ValueError, match=match):
        compare(**args)
    with pytest.raises(ValueError, match="backend must be one of"):
        compare_backends([0, 0], [1, 1], backends=["ipopt", "sqp"])


def test_comparison_to_dict_is_json_ready() -> None:
    import json

    comparison = compare_backends([0, 0], [1, 0], [[0.5, 0.8]], backends=["lm"], repeats=1)
    assert isinstance(comparison, Comparison)
    payload = json.loads(json.dumps(comparison.to_dict()))
    assert payload["obstacles"] == [[0.5, 0.8, 0.0]] and payload["rows"][0]["name"] == "lm"
    with pytest.raises(KeyError):
        comparison["ipopt"]


def _gp_smoothness(waypoints: np.ndarray, velocities: np.ndarray, dt: float) -> float:
    """Eq. 3.6 written out: sum_i e_i^T Q_i^{-1} e_i, e_i = [x_{i+1} - x_i - v_i dt;
    v_{i+1} - v_i], Q_i^{-1} = [[12/dt^3, -6/dt^2], [-6/dt^2, 4/dt]] (x) I_2."""
    total = 0.0
    for i in range(len(waypoints) - 1):
        e_pos = waypoints[i + 1] - waypoints[i] - velocities[i] * dt
        e_vel = velocities[i + 1] - velocities[i]
        total += (12 / dt**3 * e_pos @ e_pos - 12 / dt**2 * e_pos @ e_vel
                  + 4 / dt * e_vel @ e_vel)
    return float(total)


def test_comparison_reports_the_smoothness_budget_each_backend_keeps() -> None:
    """IPOPT keeps h_smooth <= sigma as a constraint; the LM backend only as a penalty, and on
    this problem reaches the subgoal by exceeding it: the comparison must say so."""
    comparison = compare_backends(start=[0, 0], subgoal=[2.5, 1],
                                  obstacles=[[1, 0.3], [0.4, -0.8], [1.8, 1.2]],
                                  backends=["ipopt", "lm"], repeats=1)
    ipopt, lm = comparison["ipopt"], comparison["lm"]
    assert ipopt.smoothness_budget == lm.smoothness_budget == 0.048
    assert ipopt.within_budget and ipopt.smoothness <= 0.048 * (1 + 1e-6)
    assert lm.reached_subgoal and not lm.within_budget and lm.smoothness > 2 * 0.048
    assert "(over, ×" in comparison.table() and lm.record()["within_budget"] is False
    for row in (ipopt, lm):
        result = row.result
        dt = ProblemSettings().dt
        assert math.isclose(row.smoothness, _gp_smoothness(result.waypoints, result.velocities, dt),
                            rel_tol=1e-9)
