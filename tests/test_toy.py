"""Toy self-paced Lagrangian (thesis §2.5.1, Fig. 2.1): known optima as oracles."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from solvers.self_paced_lagrangian import (
    GLOBAL_OPTIMUM_VALUE,
    LOCAL_OPTIMUM_VALUE,
    SelfPacedLagrangianToy,
    ToyProblem,
)
from solvers.threshold_schedule import (
    ThresholdSchedule,
    literal_threshold_index,
    threshold_schedule,
)

PI = math.pi
# A few starts per interval of Fig. 2.1's discussion (§2.5.1): the wrong component
# [-5pi/2, -3pi/2], the component right of 3pi/2 ([3pi/2 + 0.1, 5pi/2]) and the optimum's own
# component [-pi/2, pi/2].
WRONG_COMPONENT_STARTS = (-7.6, -6.2, -5.0)
OTHER_STARTS = (3 * PI / 2 + 0.1, 7.3, -PI / 2 + 0.05, 0.9)
ALL_STARTS = WRONG_COMPONENT_STARTS + OTHER_STARTS


@pytest.fixture(scope="module")
def toy() -> SelfPacedLagrangianToy:
    return SelfPacedLagrangianToy()


def _assert_global(f: float, c: float) -> None:
    assert abs(f - GLOBAL_OPTIMUM_VALUE) <= 1e-3, f"f = {f}, f* = {GLOBAL_OPTIMUM_VALUE}"
    assert c <= 1e-4, f"c = {c}"


def test_optimum_constants_match_closed_form() -> None:
    assert GLOBAL_OPTIMUM_VALUE == pytest.approx((PI / 2) ** 2 / 50, abs=1e-15)
    assert LOCAL_OPTIMUM_VALUE == pytest.approx((-3 * PI / 2 - PI) ** 2 / 50, abs=1e-15)
    assert LOCAL_OPTIMUM_VALUE == pytest.approx(1.2337, abs=1e-4)


def test_threshold_schedule_values() -> None:
    assert threshold_schedule(3, 8) == (8.0, 4.0, 2.0, 1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.0)
    assert threshold_schedule(0, 0) == (1.0, 0.0)
    assert threshold_schedule(-1, 2) == (0.5, 0.25, 0.125, 0.0)


@pytest.mark.parametrize(
    ("cost", "expected"),
    [(9.0, 8.0), (8.0, 8.0), (5.0, 4.0), (1.5, 1.0), (0.04, 0.03125), (0.01, 0.0), (-1.0, 0.0)],
)
def test_literal_threshold_index_picks_largest_threshold_not_above_cost(
    cost: float, expected: float
) -> None:
    schedule = threshold_schedule(3, 8)
    assert schedule[literal_threshold_index(cost, schedule)] == expected


@pytest.mark.parametrize("x", [-5.0, 0.0, 1.0, PI, 4.2])
def test_toy_problem_casadi_terms_match_hand_derivatives(x: float) -> None:
    f, c, df, dc = ToyProblem().evaluate(x)
    assert f == pytest.approx((x - PI) ** 2 / 50, abs=1e-14)
    assert c == pytest.approx(-5 * math.cos(x), abs=1e-14)
    assert df == pytest.approx(2 * (x - PI) / 50, abs=1e-14)
    assert dc == pytest.approx(5 * math.sin(x), abs=1e-14)


@pytest.mark.parametrize("x0", ALL_STARTS)
def test_self_paced_lagrangian_reaches_global_optimum(
    toy: SelfPacedLagrangianToy, x0: float
) -> None:
    result = toy.self_paced(x0)
    _assert_global(result.f, result.c)
    assert result.reached_global
    assert result.threshold == 0.0  # the curriculum finished at the target
    assert min(abs(result.x - PI / 2), abs(result.x - 3 * PI / 2)) < 0.02


@pytest.mark.parametrize("x0", ALL_STARTS)
def test_ipopt_homotopy_reaches_global_optimum(toy: SelfPacedLagrangianToy, x0: float) -> None:
    result = toy.ipopt_homotopy(x0)
    _assert_global(result.f, result.c)
    assert result.success and result.reached_global
    assert result.x_path[0] == pytest.approx(PI, abs=1e-6)  # loosest stage: unconstrained min
    assert result.thresholds.tolist() == list(threshold_schedule(3, 8))


@pytest.mark.parametrize("x0", WRONG_COMPONENT_STARTS)
def test_plain_lagrangian_stops_at_local_optimum(toy: SelfPacedLagrangianToy, x0: float) -> None:
    result = toy.lagrangian(x0)
    assert result.f == pytest.approx(LOCAL_OPTIMUM_VALUE, abs=1e-3)
    assert result.x == pytest.approx(-3 * PI / 2, abs=1e-3)
    assert not result.reached_global


@pytest.mark.parametrize("x0", WRONG_COMPONENT_STARTS)
def test_literal_threshold_rule_is_trapped_like_plain(
    toy: SelfPacedLagrangianToy, x0: float
) -> None:
    # Eq. 2.9 read literally never relaxes the multiplier while infeasible (d_i <= c), so from the
    # wrong component it behaves like the plain Lagrangian: the reason "tighten" is the default.
    result = toy.self_paced(x0, threshold_rule="literal")
    assert result.f == pytest.approx(LOCAL_OPTIMUM_VALUE, abs=1e-3)


@pytest.mark.parametrize("x0", [-5.0, -7.0])
def test_ipopt_direct_solve_is_local(toy: SelfPacedLagrangianToy, x0: float) -> None:
    result = toy.ipopt_direct(x0)
    assert result.success
    assert result.x == pytest.approx(-3 * PI / 2, abs=1e-7)
    # KKT multiplier at -3pi/2: f' + lam c' = 0 with f' = -pi/10, c' = 5
    assert result.lagrange_multiplier == pytest.approx(PI / 50, abs=1e-7)


def test_multistart_ipopt_finds_global_optimum_within_1e_8(toy: SelfPacedLagrangianToy) -> None:
    result = toy.global_reference()
    assert abs(result.f - GLOBAL_OPTIMUM_VALUE) <= 1e-8
    assert min(abs(result.x - PI / 2), abs(result.x - 3 * PI / 2)) <= 1e-6
    assert result.c <= 1e-8
    assert result.lagrange_multiplier == pytest.approx(PI / 250, abs=1e-7)  # f' = -pi/50, c' = 5


def test_dynamics_result_is_frozen_with_full_history(toy: SelfPacedLagrangianToy) -> None:
    small = SelfPacedLagrangianToy(n_iterations=50)
    result = small.self_paced(-5.0)
    assert result.x_history.shape == (51,) and result.threshold_history.shape == (51,)
    assert result.x_history[0] == -5.0 and result.x_history[-1] == result.x
    assert result.threshold_history[0] == 8.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.x = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        result.x_history[0] = 1.0


def test_dynamics_are_deterministic() -> None:
    first = SelfPacedLagrangianToy(n_iterations=500).self_paced(-5.0)
    second = SelfPacedLagrangianToy(n_iterations=500).self_paced(-5.0)
    np.testing.assert_array_equal(first.x_history, second.x_history)


@pytest.mark.parametrize("x0", ["abc", float("nan"), float("inf"), None, True, [1.0]])
def test_bad_start_raises_value_error_naming_x0(toy: SelfPacedLagrangianToy, x0: object) -> None:
    for method in (toy.lagrangian, toy.self_paced, toy.ipopt_direct, toy.ipopt_homotopy):
        with pytest.raises(ValueError, match="x0"):
            method(x0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"num_thresholds": -1}, "num_thresholds"),
        ({"initial_exponent": 2.5}, "initial_exponent"),
        ({"lr_x": 0.0}, "lr_x"),
        ({"lr_x": -0.1}, "lr_x"),
        ({"lr_x": "fast"}, "lr_x"),
        ({"lr_lambda": 0.0}, "lr_lambda"),
        ({"lambda_init": -1.0}, "lambda_init"),
        ({"lambda_optimizer": "rmsprop"}, "lambda_optimizer"),
        ({"lambda_update_every": 0}, "lambda_update_every"),
        ({"n_iterations": 0}, "n_iterations"),
        ({"lr_decay": 0.0}, "lr_decay"),
        ({"lr_decay": 2.0}, "lr_decay"),
        ({"adam_beta2": 1.0}, "adam_beta2"),
        ({"threshold_rule": "loose"}, "threshold_rule"),
        ({"stationarity_tol": float("nan")}, "stationarity_tol"),
        ({"multistart_points": 0}, "multistart_points"),
        ({"multistart_range": (1.0, -1.0)}, "multistart_range"),
    ],
)
def test_bad_setting_raises_value_error_naming_it(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        SelfPacedLagrangianToy(**kwargs)  # type: ignore[arg-type]


def test_bad_threshold_rule_override_raises(toy: SelfPacedLagrangianToy) -> None:
    with pytest.raises(ValueError, match=r"threshold_rule.*tighten"):
        toy.self_paced(-5.0, threshold_rule="sometimes")


GRID = (
    tuple(np.linspace(-5 * PI / 2, -3 * PI / 2, 8))
    + tuple(np.linspace(3 * PI / 2 + 0.1, 5 * PI / 2, 6))
    + tuple(np.linspace(-PI / 2, PI / 2, 6))
)


@pytest.mark.slow
def test_acceptance_grid_of_20_starts(toy: SelfPacedLagrangianToy) -> None:
    """Every start of the 20-point grid, both SP variants reach the optimum."""
    for x0 in GRID:
        for result in (toy.self_paced(x0), toy.ipopt_homotopy(x0)):
            _assert_global(result.f, result.c)
        if x0 <= -3 * PI / 2:
            assert toy.lagrangian(x0).f == pytest.approx(LOCAL_OPTIMUM_VALUE, abs=1e-3)


def test_threshold_schedule_drops_values_at_or_below_the_target_and_keeps_it_last() -> None:
    assert threshold_schedule(8, 3, target=25.0) == (256.0, 128.0, 64.0, 32.0, 25.0)
    assert threshold_schedule(6, 4, target=40.0) == (64.0, 40.0)
    assert threshold_schedule(2, 1, target=0.0, base=3.0) == (9.0, 3.0, 0.0)
    for bad in ({"target": -1.0}, {"target": math.inf}, {"base": 1.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            threshold_schedule(3, 2, **bad)



def test_threshold_schedule_rules_step_as_documented() -> None:
    sched = ThresholdSchedule(threshold_schedule(3, 2), "tighten")
    seen = [sched.select(5.0, done) for done in (False, True, True, True, True)]
    assert seen == [8.0, 4.0, 2.0, 0.0, 0.0]
    literal = ThresholdSchedule(threshold_schedule(3, 2), "literal", index=3)
    assert literal.current == 0.0
    assert [literal.select(c, False) for c in (9.0, 3.0, 0.5)] == [8.0, 2.0, 0.0]
    with pytest.raises(ValueError, match="rule"):
        ThresholdSchedule((1.0, 0.0), "loosen")
