"""The robot-model side of the low-level safety filter (:mod:`semdp.embedded.shield`): the
trajectory a certificate checks (the proposed action, then the braking manoeuvre) and the time
at which each of its points meets a moving region (gremlins, under the reach bound stated in
the filter's docstring)."""

from __future__ import annotations

import numpy as np

from semdp.embedded.robot_models import RobotModel, RobotState

#: How long (s) an escape from a moving region is held in its score before braking.
ESCAPE_HOLD_S = 0.3
#: How much deeper (m) than the robot already is an escape may go into a region.
ESCAPE_SLACK = 0.01
#: How much worse (m) than the best the last escape may score and still be kept.
KEEP_SLACK = 0.002


def trajectory(model: RobotModel, state: RobotState, first: np.ndarray,
                hold: int = 1) -> np.ndarray:
    """Root positions ``(hold + horizon, 2)``: ``first`` for ``hold`` steps, then braking."""
    points = np.empty((model.horizon + hold, 2))
    s = state
    for i in range(hold):
        s = model.step(s, first)
        points[i] = (s.x, s.y)
    points[hold:] = model.brake_path(s)
    return points


def step_seconds(model: RobotModel) -> float:
    """The model's env step (s)."""
    return float(model.h * model.substeps)  # type: ignore[attr-defined]


#: How long (s) a certificate keeps the robot clear of a gremlin's reach once its braking
#: manoeuvre has brought it to rest (:mod:`semdp.embedded.shield`).
GREMLIN_HOLD_S = 0.8
#: The braking manoeuvre has come to rest where the rest of it covers less than this (m).
AT_REST = 0.005


def seconds_ahead(model: RobotModel, points: np.ndarray) -> np.ndarray:
    """The time (s) at which a moving region is checked against each certificate point: its
    own time ``(i + 1) dt``, at most :data:`GREMLIN_HOLD_S` past the time the manoeuvre has
    come to rest."""
    ahead = step_seconds(model) * np.arange(1, len(points) + 1)
    remaining = np.linalg.norm(points - points[-1], axis=1)
    rest = int(np.argmax(remaining < AT_REST))
    return np.minimum(ahead, ahead[rest] + GREMLIN_HOLD_S)
