"""Every planner satisfies the ``Planner`` protocol (solvers/planner/protocol.py) and a planner's
parts do not (the comparison refuses them), every backend the ``Backend`` protocol
(solvers/planner/backends/base.py), and the straight-line ablation planner refuses a rescue."""

from __future__ import annotations

import numpy as np
import pytest

from semdp.embedded.straight import StraightLinePlanner
from solvers.planner import (
    LMSettings,
    Planner,
    PlanResult,
    ProblemSettings,
    SafeTrajectoryPlanner,
    compare,
)
from solvers.planner.backends import Backend

PLANNERS = {
    "ipopt": lambda: SafeTrajectoryPlanner(backend="ipopt"),
    "lm": lambda: SafeTrajectoryPlanner(backend="lm"),
    "lm_adaptive": lambda: SafeTrajectoryPlanner(backend=LMSettings(adaptive=True)),
    "scp": lambda: SafeTrajectoryPlanner(backend="scp"),
    "lm+rescue": lambda: SafeTrajectoryPlanner(backend="lm", rescue_backend="ipopt"),
    "straight": lambda: StraightLinePlanner(),
}


@pytest.mark.parametrize("name", list(PLANNERS))
def test_every_planner_is_a_planner_and_returns_a_plan_result(name: str) -> None:
    planner = PLANNERS[name]()
    assert isinstance(planner, Planner)
    result = planner.plan([0.0, 0.0], [2.0, 1.0], [[1.0, 0.3, 0.0], [0.4, -0.8, 0.1]],
                          warm_start=False)
    assert isinstance(result, PlanResult)
    assert result.waypoints.shape == (planner.n_waypoints, 2)
    np.testing.assert_allclose(result.waypoints[0], [0.0, 0.0])
    assert isinstance(result.summary(), str)


def test_backends_satisfy_the_backend_protocol() -> None:
    for backend in ("ipopt", "lm", "scp"):
        assert isinstance(SafeTrajectoryPlanner(backend=backend).solver, Backend)
    assert isinstance(SafeTrajectoryPlanner(backend="scp", rescue_backend="ipopt").rescue_solver,
                      Backend)


@pytest.mark.parametrize("part", ["settings", "backend"])
def test_a_planners_part_given_as_a_planner_is_refused_naming_it(part: str) -> None:
    """A backend or its settings (parts of a planner, without ``plan``, ``n_waypoints`` and
    ``clearance``) where a planner belongs: the comparison refuses it in one line."""
    given = LMSettings() if part == "settings" else SafeTrajectoryPlanner(backend="lm").solver
    assert not isinstance(given, Planner)
    with pytest.raises(ValueError, match="planner 'lm' has no plan\\(\\), n_waypoints"):
        compare([0.0, 0.0], [1.0, 0.0], planners={"lm": given})


def test_straight_planner_has_no_solver() -> None:
    assert StraightLinePlanner(rescue_backend=None).rescue_backend is None
    with pytest.raises(ValueError, match="no solver: rescue_backend must be None"):
        StraightLinePlanner(rescue_backend="ipopt")
    with pytest.raises(ValueError, match="no solver: backend must be None"):
        StraightLinePlanner(backend="lm")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="problem must be a ProblemSettings"):
        StraightLinePlanner(problem={"n_waypoints": 3})  # type: ignore[arg-type]


def test_straight_plan_reports_its_clearance_along_the_segment() -> None:
    planner = StraightLinePlanner(ProblemSettings(n_waypoints=3))
    plan = planner.plan([0, 0], [2, 0], [[1.0, 0.6, 0.1]])
    assert plan.reached_subgoal and plan.objective == 0.0 and plan.backend == "straight"
    assert plan.min_clearance == pytest.approx(0.6 - 0.1)  # the middle waypoint is at (1, 0)
    assert plan.min_clearance_continuous == pytest.approx(0.5)
    assert plan.feasible  # 0.5 >= eps' = 0.5
    strict = StraightLinePlanner(ProblemSettings(clearance=0.6))
    assert not strict.plan([0, 0], [2, 0], [[1.0, 0.6, 0.1]]).feasible
