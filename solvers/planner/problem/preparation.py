"""One planning problem, validated and reduced to what a backend needs (thesis §3.5.2).

:func:`prepare` checks the start, subgoal and obstacles (``ValueError`` on bad input), moves them
into the start-relative frame of :mod:`.gp_prior`, computes each obstacle's required clearance
``eps' + r_j`` (Eq. 3.7) and selects the obstacles a backend is given: those a plan within the
smoothness budget can reach, nearest first. A start inside some clearance puts the problem in
escape mode (docs/planner.md, "Backends"): those obstacles then require "no closer than the
start".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.planner.geometry import point_distances

#: Escape mode: a waypoint may be at most this much (m) closer to a violated obstacle than the
#: start is (the solvers are asked for a tenth of it, so their tolerances fit in between).
ESCAPE_TOLERANCE = 1e-6


@dataclass
class PreparedProblem:
    """One validated problem in the start-relative frame, ready for a backend.

    Attributes:
        start: Start s in world coordinates (2,).
        goal: Subgoal minus start (2,).
        centres: All obstacle centres minus start (m, 2).
        clearances: Required clearance ``eps' + r_j`` per obstacle (m,).
        selected: Indices into ``centres`` of the obstacles given to the backend (reachable ones,
            nearest first, at most ``max_obstacles``).
        escape: Boolean per obstacle: the start is inside its clearance (escape mode).
        required: Clearance each waypoint must keep per obstacle: ``clearances``, or the start's
            own distance (less ``ESCAPE_TOLERANCE``) for escape obstacles ("do not get closer").
    """

    start: np.ndarray
    goal: np.ndarray
    centres: np.ndarray
    clearances: np.ndarray
    selected: np.ndarray
    escape: np.ndarray
    required: np.ndarray
    start_distances: np.ndarray

    @property
    def escape_mode(self) -> bool:
        """True when the start violates the clearance of at least one obstacle."""
        return bool(self.escape.any())


def validate_point(name: str, value: object) -> np.ndarray:
    """Return ``value`` as a finite float array of shape (2,) or raise ValueError."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be a 2-vector of numbers, got {value!r}") from error
    if array.shape != (2,):
        raise ValueError(f"{name} must have shape (2,), got shape {array.shape}: {value!r}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    return array


def validate_obstacles(obstacles: object) -> tuple[np.ndarray, np.ndarray]:
    """Centres (m, 2) and radii (m,) from an (m, 2) or (m, 3) array-like; raise ValueError."""
    if obstacles is None:
        return np.zeros((0, 2)), np.zeros(0)
    try:
        array = np.asarray(obstacles, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"obstacles must be an (m, 2) array of centres or (m, 3) of [x, y, radius], "
            f"got {obstacles!r}"
        ) from error
    if array.size == 0:
        return np.zeros((0, 2)), np.zeros(0)
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise ValueError(
            "obstacles must have shape (m, 2) (centres) or (m, 3) (centres and radii), "
            f"got shape {array.shape}"
        )
    if not np.isfinite(array).all():
        raise ValueError(f"obstacles must be finite, got {array.tolist()}")
    radii = array[:, 2].copy() if array.shape[1] == 3 else np.zeros(len(array))
    if (radii < 0).any():
        raise ValueError(f"obstacle radii must be >= 0, got {radii.tolist()}")
    return array[:, :2].copy(), radii


def prepare(
    start: object,
    subgoal: object,
    obstacles: object,
    *,
    clearance: float,
    reach: float,
    max_obstacles: int,
) -> PreparedProblem:
    """Validate the inputs and select the obstacles a backend has to consider.

    Obstacles whose clearance disc lies beyond ``reach`` (the farthest any admissible waypoint can
    get from the start) are dropped; of the rest, the ``max_obstacles`` nearest (by distance minus
    clearance) are kept. The certificate still checks every obstacle given.
    """
    start_arr = validate_point("start", start)
    goal_arr = validate_point("subgoal", subgoal) - start_arr
    centres, radii = validate_obstacles(obstacles)
    centres = centres - start_arr
    clearances = clearance + radii
    start_distances = point_distances(np.zeros((1, 2)), centres)[0]  # x_1 = start: Eq. 3.7
    gaps = start_distances - clearances
    escape = gaps < 0.0
    candidates = np.flatnonzero(gaps <= reach)
    order = candidates[np.argsort(gaps[candidates], kind="stable")]
    selected = order[:max_obstacles]
    required = np.where(escape, start_distances - ESCAPE_TOLERANCE, clearances)
    return PreparedProblem(
        start_arr, goal_arr, centres, clearances, selected, escape, required, start_distances
    )
