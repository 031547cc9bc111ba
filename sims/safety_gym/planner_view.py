"""The planner's view of a Safety Gym task: robot pose and velocity, goal, box, obstacles.

Ground-truth accessors for the Safety-Embedded MDP's planner (thesis §3.5, App. B.2.1: the
root node is the planned point; obstacles are discs ``[x, y, radius]``). docs/simulators.md
("The planner's view, perception, rendering") lists them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pymunk

from sims.safety_gym import config as cfg
from sims.safety_gym.robots import Robot

OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins", "buttons")
DEFAULT_OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins")
_SQRT2 = math.sqrt(2.0)


class PlannerView:
    """Mixin of :class:`~sims.safety_gym.env.SafetyGymEnv`: poses and obstacles as arrays."""

    robot: Robot
    body: pymunk.Body
    box_body: pymunk.Body | None
    goal_x: float
    goal_y: float
    hazard_radius: float
    pillar_radius: float
    hazards: list[tuple[float, float]]
    pillars: list[tuple[float, float]]
    buttons: list[tuple[float, float]]
    vase_bodies: list[pymunk.Body]
    gremlin_bodies: list[pymunk.Body]
    gremlin_xy: list[list[float]]

    @property
    def robot_position(self) -> np.ndarray:
        """Root-node position ``(x, y)`` in metres (thesis App. B.2.1)."""
        return np.array(self.body.position, dtype=np.float64)

    @property
    def robot_heading(self) -> float:
        """Body yaw (rad): the LiDAR and sensor frame. The Point and Mass drive along it; the
        Car drives along ``robot_heading + robot.forward_offset`` (body −y)."""
        return float(self.body.angle)

    @property
    def robot_forward_heading(self) -> float:
        """Yaw of the driving direction (rad)."""
        return float(self.body.angle + self.robot.forward_offset)

    @property
    def robot_velocity(self) -> np.ndarray:
        """Linear velocity ``(vx, vy)`` in the world frame (m/s)."""
        return np.array(self.body.velocity, dtype=np.float64)

    @property
    def goal_position(self) -> np.ndarray:
        """The goal centre (Button: the current goal button)."""
        return np.array((self.goal_x, self.goal_y), dtype=np.float64)

    @property
    def box_position(self) -> np.ndarray | None:
        """The push box centre, or ``None`` outside the Push task."""
        if self.box_body is None:
            return None
        return np.array(self.box_body.position, dtype=np.float64)

    def obstacles_by_type(self) -> dict[str, np.ndarray]:
        """Ground-truth ``[x, y, radius]`` rows per present obstacle type.

        Radii: hazards 0.2 (0.3 in Push), pillars 0.2, buttons 0.1; vases and gremlins (cubes of
        half-size 0.1) get their circumscribed radius 0.1·√2. Gremlins are reported where they
        are now. Types absent from the task are omitted.
        """
        out: dict[str, np.ndarray] = {}
        if self.hazards:
            out["hazards"] = np.array([(x, y, self.hazard_radius) for x, y in self.hazards])
        if self.vase_bodies:
            r = cfg.VASE_HALF * _SQRT2
            out["vases"] = np.array([(*b.position, r) for b in self.vase_bodies])
        if self.pillars:
            out["pillars"] = np.array([(x, y, self.pillar_radius) for x, y in self.pillars])
        if self.gremlin_bodies:
            r = cfg.GREMLIN_HALF * _SQRT2
            out["gremlins"] = np.array([(x, y, r) for x, y in self.gremlin_xy])
        if self.buttons:
            out["buttons"] = np.array([(x, y, cfg.BUTTON_RADIUS) for x, y in self.buttons])
        return out

    def obstacles(self, kinds: Iterable[str] = DEFAULT_OBSTACLE_KINDS) -> np.ndarray:
        """Ground-truth obstacles ``(m, 3)`` of ``[x, y, radius]`` for the requested types.

        Raises:
            ValueError: for a type that is not an obstacle type (valid: hazards, vases,
                pillars, gremlins, buttons).
        """
        kinds = tuple(kinds)
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad:
            raise ValueError(f"unknown obstacle kinds {bad}; valid: {list(OBSTACLE_KINDS)}")
        by_type = self.obstacles_by_type()
        rows = [by_type[k] for k in kinds if k in by_type]
        return np.concatenate(rows) if rows else np.zeros((0, 3))
