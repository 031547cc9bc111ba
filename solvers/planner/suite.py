"""Seeded random planning problems: the benchmark suite and the property tests
(docs/planner.md, "Benchmark").

Problems look like the Safety-Embedded MDP's calls: a start, a subgoal within +-2 m of it (per
axis, as the policy's action box), 0-8 obstacle centres within a few metres, and in a share of the
problems the start just outside an obstacle's clearance. Every start keeps the clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.planner.problem.settings import ProblemSettings


@dataclass(frozen=True)
class PlanningProblem:
    """One planning problem: start (2,), subgoal (2,), obstacles (m, 2) or (m, 3)."""

    start: np.ndarray
    subgoal: np.ndarray
    obstacles: np.ndarray


def random_problems(
    n: int,
    seed: int = 0,
    *,
    clearance: float = ProblemSettings.clearance,
    max_count: int = 8,
    subgoal_range: float = 2.0,
    obstacle_range: float = 3.0,
    near_start_share: float = 0.25,
    radius_share: float = 0.0,
) -> list[PlanningProblem]:
    """Draw ``n`` problems deterministically from ``seed``.

    Args:
        n: Number of problems.
        seed: Seed of ``numpy.random.default_rng``.
        clearance: eps'; every start keeps at least this distance (plus radius) to every obstacle.
        max_count: Obstacle counts are uniform in ``0..max_count``.
        subgoal_range: Subgoal offsets are uniform in ``[-subgoal_range, subgoal_range]^2``.
        obstacle_range: Obstacle offsets from the start are uniform in ``[-r, r]^2``.
        near_start_share: Share of problems whose first obstacle sits 0-0.1 m outside the start's
            clearance.
        radius_share: Share of problems whose obstacles carry radii in [0, 0.3] (shape (m, 3)).
    """
    rng = np.random.default_rng(seed)
    problems: list[PlanningProblem] = []
    for _ in range(n):
        start = rng.uniform(-3.0, 3.0, size=2)
        subgoal = start + rng.uniform(-subgoal_range, subgoal_range, size=2)
        count = int(rng.integers(0, max_count + 1))
        with_radius = rng.random() < radius_share
        near = count > 0 and rng.random() < near_start_share
        rows: list[np.ndarray] = []
        while len(rows) < count:
            radius = rng.uniform(0.0, 0.3) if with_radius else 0.0
            if near and not rows:
                angle = rng.uniform(0.0, 2.0 * np.pi)
                distance = clearance + radius + rng.uniform(0.0, 0.1)
                centre = start + distance * np.array([np.cos(angle), np.sin(angle)])
            else:
                centre = start + rng.uniform(-obstacle_range, obstacle_range, size=2)
                if np.hypot(*(centre - start)) < clearance + radius:
                    continue
            rows.append(np.append(centre, radius) if with_radius else centre)
        obstacles = np.array(rows).reshape(-1, 3 if with_radius else 2)
        problems.append(PlanningProblem(start, subgoal, obstacles))
    return problems
