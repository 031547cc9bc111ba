"""CPO's subproblem in each of its five cases against a small quadratic problem with a known
answer: max g'D s.t. c + b'D <= 0, D'HD/2 <= delta (solved independently with SLSQP)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from semdp.algos.cpo import cpo_dual, cpo_step

H = np.array([[2.0, 0.3], [0.3, 1.0]])
G = np.array([1.0, 0.5])
DELTA = 0.5


def _cpo(b: np.ndarray, c: float) -> tuple[int, np.ndarray]:
    x, p = np.linalg.solve(H, G), np.linalg.solve(H, b)
    dual = cpo_dual(float(G @ x), float(G @ p), float(b @ p), c, DELTA, float(b @ b))
    return dual.case, cpo_step(x, p, dual)


def _reference(b: np.ndarray, c: float) -> np.ndarray:
    """Best of several SLSQP starts on the primal QCQP."""
    cons = [
        {"type": "ineq", "fun": lambda d: DELTA - 0.5 * d @ H @ d},
        {"type": "ineq", "fun": lambda d: -(c + b @ d)},
    ]
    best = None
    for start in ([0.0, 0.0], [0.3, -0.3], [-0.3, 0.3], [-0.2, -0.2]):
        res = minimize(lambda d: -G @ d, np.array(start), constraints=cons, method="SLSQP",
                       options={"ftol": 1e-12, "maxiter": 500})
        feasible = all(con["fun"](res.x) >= -1e-7 for con in cons)
        if feasible and (best is None or G @ res.x > G @ best):
            best = res.x
    assert best is not None
    return best


def _trpo_step() -> np.ndarray:
    x = np.linalg.solve(H, G)
    return math.sqrt(2 * DELTA / (G @ x)) * x


def test_cpo_case4_vanishing_cost_gradient_gives_the_trpo_step() -> None:
    case, step = _cpo(np.zeros(2), -1.0)
    assert case == 4
    np.testing.assert_allclose(step, _trpo_step(), atol=1e-9)


def test_cpo_case3_whole_trust_region_feasible_gives_the_trpo_step() -> None:
    b, c = np.array([1.0, 0.0]), -10.0
    case, step = _cpo(b, c)
    assert case == 3
    np.testing.assert_allclose(step, _trpo_step(), atol=1e-9)
    np.testing.assert_allclose(step, _reference(b, c), atol=1e-4)


@pytest.mark.parametrize(
    ("b", "active"),
    [(np.array([1.0, -0.3]), True), (np.array([-1.0, 0.2]), False)],
    ids=["constraint-active", "constraint-inactive"],
)
def test_cpo_case2_feasible_cut_trust_region_matches_qcqp(b: np.ndarray, active: bool) -> None:
    c = -0.05
    case, step = _cpo(b, c)
    assert case == 2
    np.testing.assert_allclose(step, _reference(b, c), atol=1e-4)
    assert math.isclose(c + b @ step, 0.0, abs_tol=1e-6) == active
    assert 0.5 * step @ H @ step == pytest.approx(DELTA, rel=1e-6)


def test_cpo_case1_infeasible_but_recoverable_matches_qcqp() -> None:
    b, c = np.array([1.0, -0.3]), 0.05
    case, step = _cpo(b, c)
    assert case == 1
    np.testing.assert_allclose(step, _reference(b, c), atol=1e-4)
    assert c + b @ step == pytest.approx(0.0, abs=1e-6)  # recovered onto the constraint


def test_cpo_case0_infeasible_recovery_minimises_cost_in_the_trust_region() -> None:
    b, c = np.array([1.0, 0.5]), 5.0
    case, step = _cpo(b, c)
    assert case == 0
    p = np.linalg.solve(H, b)
    np.testing.assert_allclose(step, -math.sqrt(2 * DELTA / (b @ p)) * p, atol=1e-12)
    res = minimize(lambda d: b @ d, np.zeros(2), method="SLSQP",
                   constraints=[{"type": "ineq", "fun": lambda d: DELTA - 0.5 * d @ H @ d}],
                   options={"ftol": 1e-12})
    np.testing.assert_allclose(step, res.x, atol=1e-4)


def test_cpo_dual_rejects_non_positive_delta() -> None:
    with pytest.raises(ValueError, match="delta"):
        cpo_dual(1.0, 0.0, 1.0, -1.0, 0.0, 1.0)
