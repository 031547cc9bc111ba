"""Receding-horizon warm start: the rest of the previous plan as the next initial guess.

The SEMDP re-plans every k steps towards a subgoal that often barely moves (thesis Alg. 2); when
it moved less than :data:`SAME_SUBGOAL` the previous plan, from its waypoint nearest to the new
start on, is a good initial guess.
"""

from __future__ import annotations

import numpy as np

from solvers.planner.problem.gp_prior import join
from solvers.planner.problem.preparation import PreparedProblem

#: A subgoal that moved less than this (m) since the previous plan counts as the same one.
SAME_SUBGOAL = 0.25


class WarmStartMemory:
    """The previous plan of one planner.

    Attributes:
        dt: Time between waypoints (s), for the guess' velocities.
        previous: (start, subgoal, waypoints) of the previous plan, all in world coordinates,
            or None before the first plan.
    """

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def remember(self, start: np.ndarray, subgoal: np.ndarray, waypoints: np.ndarray) -> None:
        """Keep a plan (copies of ``start`` and ``waypoints``) for the next :meth:`guess`."""
        self.previous = (start.copy(), subgoal, waypoints.copy())

    def guess(self, prep: PreparedProblem) -> np.ndarray | None:
        """The previous plan from its waypoint nearest to the new start on, padded with its
        last waypoint; None when there is none or the subgoal moved."""
        if self.previous is None:
            return None
        _, previous_goal, waypoints = self.previous
        if np.hypot(*(prep.start + prep.goal - previous_goal)) > SAME_SUBGOAL:
            return None
        rest = waypoints - prep.start
        nearest = int(np.argmin(np.einsum("nk,nk->n", rest, rest)))
        positions = np.zeros_like(rest)
        tail = rest[nearest + 1 :]
        positions[1 : 1 + len(tail)] = tail
        positions[1 + len(tail) :] = rest[-1]
        velocities = np.zeros_like(positions)
        velocities[1:] = np.diff(positions, axis=0) / self.dt
        return join(positions, velocities)
