"""The detour guess (solvers/planner/problem/initial_guess.py; thesis §3.5.2): its obstacles'
nearest waypoints found for all obstacles at once, against a one-obstacle-at-a-time oracle."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from solvers.planner.problem.gp_prior import GPPrior, build_gp_prior
from solvers.planner.problem.initial_guess import detour_guess


def _one_at_a_time(prior: GPPrior, goal: np.ndarray, centres: np.ndarray,
                   clearances: np.ndarray, reach: float, inflate: float = 1.15) -> np.ndarray:
    """The guess as its docstring states it, obstacle by obstacle (the form before the
    obstacles were handled together)."""
    straight = detour_guess(prior, goal, np.zeros((0, 2)), np.zeros(0), reach=reach)
    if len(centres) == 0 or not np.any(goal):
        return straight
    target = goal * min(1.0, reach / float(np.hypot(goal[0], goal[1])))
    n = prior.n_waypoints - 1
    positions = straight[: 2 * n].reshape(n, 2)
    unit = target / max(float(np.hypot(target[0], target[1])), 1e-12)
    left = np.array([-unit[1], unit[0]])
    rows: list[int] = []
    points: list[np.ndarray] = []
    for centre, radius in zip(centres, clearances, strict=True):
        rel = positions - centre
        dist = np.sqrt(rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1])
        k = int(np.argmin(dist))
        if dist[k] >= radius * inflate or k == n - 1 or k in rows:
            continue
        side = -1.0 if float(centre @ left) > 0.0 else 1.0
        foot = centre + ((positions[k] - centre) @ unit) * unit
        rows.append(k)
        points.append(foot + side * left * radius * inflate)
    if not rows:
        return straight
    cols = np.ravel([[2 * k, 2 * k + 1] for k in [*rows, n - 1]])
    select = prior.hessian_inv[:, cols]
    return select @ sla.solve(select[cols], np.concatenate([*points, target]), assume_a="pos")


def test_the_guess_equals_the_one_obstacle_at_a_time_oracle_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    bent = 0
    for n_waypoints in (10, 16):
        prior = build_gp_prior(n_waypoints, 0.1)
        for trial in range(400):
            m = int(rng.integers(0, 16))
            goal = rng.uniform(-3.0, 3.0, 2)
            centres = rng.uniform(-2.5, 2.5, (m, 2))
            if m and trial % 5 == 0:  # a centre on the straight line: the left side is taken
                centres[0] = goal * rng.uniform(0.1, 0.9)
            clearances = rng.uniform(0.1, 0.8, m)
            got = detour_guess(prior, goal, centres, clearances, reach=2.0)
            expected = _one_at_a_time(prior, goal, centres, clearances, reach=2.0)
            np.testing.assert_array_equal(got, expected)
            bent += not np.array_equal(got, prior.goal_map @ (
                goal if np.hypot(*goal) <= 2.0 else goal * (2.0 / np.hypot(*goal))))
    assert bent > 200  # most trials had obstacles on the way, so the detour was exercised


def test_an_obstacle_on_the_straight_line_is_passed_on_the_left() -> None:
    prior = build_gp_prior(10, 0.1)
    goal = np.array([2.0, 0.0])
    guess = detour_guess(prior, goal, np.array([[1.0, 0.0]]), np.array([0.4]), reach=2.0)
    waypoints = guess[: 2 * 9].reshape(9, 2)
    assert waypoints[:, 1].max() > 0.4  # bent to +y, the left of the line
    assert np.hypot(*(waypoints - [1.0, 0.0]).T).min() > 0.3
    np.testing.assert_allclose(waypoints[-1], goal, atol=1e-9)
