"""Observation of the Safety Gym replica: robot sensors, then one pseudo-LiDAR per object type.

Layout as in docs/simulators.md ("What is replicated", Observation): accelerometer (body frame,
+9.81 in z), velocimeter, gyro, magnetometer (the Car adds its rear-ball sensors), then 16-bin
pseudo-LiDAR channels in Safety-Gymnasium's insertion order of the task's object types.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import gymnasium
import numpy as np
import pymunk

from sims.safety_gym import config as cfg
from sims.safety_gym.lidar import fill_pseudo_lidar
from sims.safety_gym.robots import Robot


class SensorObservation:
    """Mixin of :class:`~sims.safety_gym.env.SafetyGymEnv`: the observation and its space."""

    robot: Robot
    layout_spec: cfg.LevelSpec
    body: pymunk.Body
    box_body: pymunk.Body | None
    goal_x: float
    goal_y: float
    hazards: list[tuple[float, float]]
    pillars: list[tuple[float, float]]
    buttons: list[tuple[float, float]]
    vase_bodies: list[pymunk.Body]
    gremlin_xy: list[list[float]]
    button_timer: int
    _last_accel: tuple[float, float]
    _extra: list[float]

    def _init_observation_space(self) -> None:
        """``obs_slices``, ``observation_space`` and ``action_space`` of this robot and task."""
        slices: dict[str, slice] = {}
        n = 0
        for name, size in self.robot.sensor_sizes:
            slices[name] = slice(n, n + size)
            n += size
        self._n_sensors = n
        self._lidar_offsets: dict[str, int] = {}
        for kind in self.layout_spec.lidar_order:
            slices[f"{kind}_lidar"] = slice(n, n + cfg.LIDAR_BINS)
            self._lidar_offsets[kind] = n
            n += cfg.LIDAR_BINS
        self.obs_slices: dict[str, slice] = slices
        low = np.full(n, -np.inf)
        high = np.full(n, np.inf)
        low[self._n_sensors :] = 0.0
        high[self._n_sensors :] = 1.0
        self.observation_space = gymnasium.spaces.Box(low, high, dtype=np.float64)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (2,), dtype=np.float64)
        self._obs_size = n

    def _observation(
        self,
        rx: float | None = None,
        ry: float = 0.0,
        vx: float = 0.0,
        vy: float = 0.0,
        box: Any = None,
    ) -> np.ndarray:
        """Sensors + pseudo-LiDAR channels, flattened in Safety-Gymnasium's order.

        The robot state may be passed in (the step already read it); otherwise it is read.
        """
        body = self.body
        if rx is None:
            rx, ry = body.position
            vx, vy = body.velocity
            box = self.box_body.position if self.box_body is not None else None
        yaw = body.angle
        c, s = math.cos(yaw), math.sin(yaw)
        ax, ay = self._last_accel
        obs = [0.0] * self._obs_size
        obs[0] = c * ax + s * ay
        obs[1] = c * ay - s * ax
        obs[2] = cfg.GRAVITY
        obs[3] = c * vx + s * vy
        obs[4] = c * vy - s * vx
        obs[8] = body.angular_velocity
        obs[9] = -0.5 * s
        obs[10] = -0.5 * c
        if self._extra:
            obs[12:24] = self._extra
        for kind, offset in self._lidar_offsets.items():
            if kind == "goal":
                points: Iterable = ((self.goal_x, self.goal_y),)
            elif kind == "hazards":
                points = self.hazards
            elif kind == "pillars":
                points = self.pillars
            elif kind == "push_box":
                points = (box,)
            elif kind == "vases":
                points = [b.position for b in self.vase_bodies]
            elif kind == "gremlins":
                points = self.gremlin_xy
            else:  # buttons: blank while the timer runs
                if self.button_timer:
                    continue
                points = self.buttons
            fill_pseudo_lidar(obs, offset, points, rx, ry, c, s)
        return np.array(obs, dtype=np.float64)
