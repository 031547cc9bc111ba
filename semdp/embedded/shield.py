"""A last-line safety filter on the follower's low-level action (beyond the thesis, §3.5.2).

The thesis' planner certifies the *plan*; the robot that follows it can still leave it: its
tracking error, its momentum at the end of a window, a box pushing back. Competent high-level
policies find those gaps (they push boxes past hazards at speed). This filter closes them with
the robot's own calibrated model (:mod:`semdp.embedded.robot_models`): before every low-level
step it simulates the proposed action for one step followed by the robot's braking manoeuvre
and keeps the action only if that whole trajectory stays out of every obstacle's cost region
(plus ``margin``). Otherwise it brakes, if braking is itself certified, and else takes the
escape action that keeps the largest clearance. By induction the robot can always stop before
a cost region it can see, whatever the subgoals (a model-predictive safety filter with a
braking backup).

Cost regions are discs around the obstacles the planner sees, by kind: hazards cost when the
root node is inside them; vases, pillars and gremlins when the robot's outline touches them,
i.e. the root within ``object radius + robot extent``. With ``perception="lidar"`` the
obstacles are re-read from the LiDAR at every checked step (exact ranges, bin-centre angles);
``"gt"`` reads the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.embedded.perception import OBSTACLE_KINDS, perceive_obstacles
from semdp.embedded.robot_models import RobotModel, RobotState, robot_model

#: Cost-region radius of each kind of object at the root node, before the robot's extent.
_CONTACT_KINDS = ("vases", "pillars", "gremlins")


@dataclass
class ShieldStats:
    """Counts since the last :meth:`SafetyShield.reset_stats`."""

    steps: int = 0
    checked: int = 0
    braked: int = 0
    escaped: int = 0


class SafetyShield:
    """Model-predictive braking filter on the low-level action (see the module docstring).

    Args:
        margin: extra clearance beyond each cost region (m).
        perception: ``"lidar"`` (the robot's own sensor, as the planner) or ``"gt"``.
        kinds: obstacle kinds filtered against.
    """

    def __init__(self, margin: float = 0.05, perception: str = "lidar",
                 kinds: tuple[str, ...] | list[str] = OBSTACLE_KINDS) -> None:
        if not margin >= 0:
            raise ValueError(f"shield margin must be >= 0, got {margin}")
        if perception not in ("lidar", "gt"):
            raise ValueError(f"shield perception must be 'lidar' or 'gt', got {perception!r}")
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad:
            raise ValueError(f"unknown obstacle kinds {bad}; valid: {list(OBSTACLE_KINDS)}")
        self.margin = float(margin)
        self.perception = perception
        self.kinds = tuple(kinds)
        self.stats = ShieldStats()
        self._model: RobotModel | None = None
        self._radii: dict[str, float] = {}

    def bind(self, base: Any) -> None:
        """Attach to the unwrapped env: its robot's model and each kind's cost radius."""
        self._model = robot_model(base.robot_name)
        sizes = {kind: float(rows[0, 2]) for kind, rows in base.obstacles_by_type().items()
                 if len(rows)}
        for kind in self.kinds:
            size = sizes.get(kind, 0.0)
            self._radii[kind] = size + (self._model.extent if kind in _CONTACT_KINDS else 0.0)

    def reset_stats(self) -> None:
        """Zero the counters."""
        self.stats = ShieldStats()

    def _regions(self, base: Any, obs: np.ndarray) -> np.ndarray:
        """``(m, 3)`` rows ``[x, y, R]``: the cost regions plus the margin."""
        rows = []
        for kind in self.kinds:
            if kind not in self._radii:
                continue
            found = perceive_obstacles(base, obs, self.perception, kinds=(kind,))
            if len(found):
                found = np.array(found, dtype=np.float64)
                found[:, 2] = self._radii[kind] + self.margin
                rows.append(found)
        return np.concatenate(rows) if rows else np.zeros((0, 3))

    def _clearance(self, model: RobotModel, state: RobotState, first: np.ndarray,
                   regions: np.ndarray) -> float:
        """Smallest ``distance - R`` over ``first`` then the braking manoeuvre."""
        points = np.empty((model.horizon + 1, 2))
        s = model.step(state, first)
        points[0] = (s.x, s.y)
        for i in range(model.horizon):
            s = model.step(s, model.backup(s))
            points[i + 1] = (s.x, s.y)
        gaps = np.linalg.norm(points[:, None, :] - regions[None, :, :2], axis=-1)
        return float((gaps - regions[None, :, 2]).min())

    def filter(self, action: np.ndarray, base: Any, obs: np.ndarray) -> np.ndarray:
        """The action to apply: ``action`` if certified, else braking, else the best escape."""
        if self._model is None:
            self.bind(base)
        model = self._model
        assert model is not None
        self.stats.steps += 1
        body = base.body
        state = RobotState(body.position.x, body.position.y, body.velocity.x, body.velocity.y,
                           body.angle, body.angular_velocity)
        regions = self._regions(base, obs)
        if not len(regions):
            return action
        distance = np.linalg.norm(regions[:, :2] - (state.x, state.y), axis=1) - regions[:, 2]
        near = distance < model.stopping_reach(state) + 0.1
        if not near.any():
            return action
        regions = regions[near]
        self.stats.checked += 1
        if self._clearance(model, state, action, regions) >= 0.0:
            return action
        brake = model.backup(state)
        if self._clearance(model, state, brake, regions) >= 0.0:
            self.stats.braked += 1
            return brake.astype(np.asarray(action).dtype)
        self.stats.escaped += 1
        options = [brake, *model.escapes]
        scores = [self._clearance(model, state, a, regions) for a in options]
        return np.asarray(options[int(np.argmax(scores))], dtype=np.asarray(action).dtype)


class ShieldedEnv(gym.Wrapper):
    """Applies a :class:`SafetyShield` to every action of a Safety Gym replica env.

    The Safety-Embedded MDP wraps this (``SafetyEmbeddedEnv(..., shield=...)``), so the
    follower's every low-level command passes the filter; ``info["shield_replaced"]`` says
    whether this step's command was replaced.
    """

    def __init__(self, env: gym.Env, shield: SafetyShield) -> None:
        super().__init__(env)
        self.shield = shield
        self._obs: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset and bind the filter to the new episode's objects."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.shield.bind(self.env.unwrapped)
        self._obs = obs
        return obs, info

    def step(self, action):
        """Filter ``action``, then step."""
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        safe = self.shield.filter(np.asarray(action), self.env.unwrapped, self._obs)
        obs, reward, terminated, truncated, info = self.env.step(safe)
        self._obs = obs
        info["shield_replaced"] = safe is not action and not np.array_equal(safe, action)
        return obs, reward, terminated, truncated, info
