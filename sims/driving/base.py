"""Safe-driving tasks of the thesis, App. A.2: follow a circle or a random path at speed v_d.

Observation (float32, bounded Box; every entry is clipped into its bounds)::

    [d, e, d_dot, e_dot, v, v_d]                      (DriveCircle-v0, 6 entries)
    [d, e, d_dot, e_dot, v, v_d, p_1x, p_1y, ..., p_Kx, p_Ky]   (DriveTrajectory-v0, 6 + 2K)

* ``d`` [m]: signed lateral distance to the centre line, positive to the left of the direction
  of travel (inside of the counter-clockwise circle); bounds +-(d_0 + margin + 1).
* ``e`` [rad]: heading error ``psi - psi_path`` wrapped to [-pi, pi).
* ``d_dot`` [m/s], ``e_dot`` [rad/s]: exact time derivatives from the Frenet kinematics,
  ``d_dot = v_x sin e + v_y cos e``, ``e_dot = r - kappa (v_x cos e - v_y sin e) / (1 - kappa d)``
  (kappa: path curvature at the projection); bounds +-20 and +-30.
* ``v`` [m/s]: speed ``hypot(v_x, v_y)``, in [0, 20]; ``v_d`` [m/s]: desired speed.
* ``p_k`` [m] (Trajectory only): centre-line points at arc lengths ``s_n + k * preview_spacing``
  (``s_n``: nearest centre-line sample, within 2.5 cm of the projection), ``k = 1..K``, in the
  car frame (x forward, y left). Defaults K = 10 points every 0.4 m (4 m of preview).

Reward (Eq. A.1 written as a cost; the agent maximises its negative)::

    r = -(d^2 + w_1 (v - v_d)^2 + w_2 * 1[|e| >= pi/2])

Cost (Eq. A.2, d_0 = half the road width): ``info["cost"] = max(|d| - d_0, 0)``, also reported
as ``info["cost_off_road"]``.

Episode end. Truncation after ``episode_length`` steps (the env counts its own steps; no
TimeLimit wrapper is registered; the Trajectory env also truncates if the car reaches the end
of its path, which needs more than 10 m/s on average). Termination when the car is far off the
road, ``|d| > d_0 + off_road_margin``; the terminal step then also collects the terminal
step's reward and cost for each remaining step of the episode (as if the car stayed there),
reported as
``info["reward_termination"]`` and ``info["cost_termination"]`` (``info["cost"]`` is the sum of
the named cost terms), so that leaving the road never shortens the penalties of an episode.
``terminate_off_road=False`` disables termination.

Actions ``[steer, throttle]`` in [-1, 1]^2: ``delta = steer * max_steer``; ``throttle >= 0``
drives the rear axle with ``throttle * max_drive_force``, ``throttle < 0`` brakes with
``throttle * max_brake_force``. Out-of-range actions are clipped; NaN raises ValueError
(:func:`sims.driving.inputs.parse_action`).

This module is the MDP both tasks share (:class:`DrivingEnv`); the tasks themselves, the
circle and the random path, are in :mod:`sims.driving.tasks`.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sims.driving.inputs import check_range, parse_action
from sims.driving.render import render_top_down
from sims.driving.tracks import CircleTrack, RandomPathTrack, wrap_angle
from sims.driving.vehicle import BicycleModel, VehicleParams

State = tuple[float, float, float, float, float, float]

D_DOT_BOUND = 20.0
E_DOT_BOUND = 30.0
SPEED_BOUND = 20.0
DESIRED_SPEED_MAX = 10.0
TRAIL_LENGTH = 300


def _clip(value: float, bound: float) -> float:
    return bound if value > bound else (-bound if value < -bound else value)


class DrivingEnv(gym.Env[np.ndarray, np.ndarray]):
    """Common dynamics, observation, reward and cost of the two driving tasks (module docstring).

    Args:
        desired_speed: v_d [m/s] in (0, 10] (the thesis sweeps 1..6).
        road_width: Road width [m]; d_0 = road_width / 2.
        episode_length: Episode length in steps (truncation).
        speed_weight: w_1 of Eq. A.1 (default 0.25, aa_simulation's CircleEnv weight).
        heading_weight: w_2 of Eq. A.1.
        dt: Control period [s]; the model takes ``ceil(dt / max_substep)`` RK4 substeps.
        max_substep: Largest RK4 substep [s].
        off_road_margin: Termination when ``|d| > d_0 + off_road_margin`` [m].
        terminate_off_road: Whether to terminate off the road at all.
        vehicle: Vehicle parameters (default: the 1/10 RC car of :class:`VehicleParams`).
        render_mode: None or ``"rgb_array"``.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        desired_speed: float = 2.0,
        road_width: float = 0.5,
        episode_length: int = 200,
        speed_weight: float = 0.25,
        heading_weight: float = 1.0,
        dt: float = 0.05,
        max_substep: float = 0.0125,
        off_road_margin: float = 0.5,
        terminate_off_road: bool = True,
        vehicle: VehicleParams | None = None,
        render_mode: str | None = None,
    ) -> None:
        check_range("desired_speed", desired_speed, 0.0, DESIRED_SPEED_MAX, "(0, 10] m/s")
        check_range("road_width", road_width, 0.0, 10.0, "(0, 10] m")
        check_range("dt", dt, 0.0, 0.2, "(0, 0.2] s")
        check_range("max_substep", max_substep, 0.0, 0.025, "(0, 0.025] s")
        check_range("off_road_margin", off_road_margin, 0.0, 10.0, "(0, 10] m")
        for name, weight in (("speed_weight", speed_weight), ("heading_weight", heading_weight)):
            if not (math.isfinite(weight) and weight >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {weight!r}")
        if int(episode_length) != episode_length or episode_length < 1:
            raise ValueError(f"episode_length must be a positive integer, "
                             f"got {episode_length!r}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or one of "
                             f"{self.metadata['render_modes']}, got {render_mode!r}")
        self.desired_speed = float(desired_speed)
        self.road_width = float(road_width)
        self.half_width = 0.5 * self.road_width
        self.episode_length = int(episode_length)
        self.speed_weight = float(speed_weight)
        self.heading_weight = float(heading_weight)
        self.dt = float(dt)
        self.substeps = max(1, math.ceil(self.dt / max_substep - 1e-9))
        self.off_road_margin = float(off_road_margin)
        self.termination_distance = self.half_width + self.off_road_margin
        self.terminate_off_road = bool(terminate_off_road)
        self.render_mode = render_mode
        self.model = BicycleModel(vehicle)
        params = self.model.params
        self._max_steer = params.max_steer
        self._max_drive = params.max_drive_force
        self._max_brake = params.max_brake_force

        self.d_bound = self.termination_distance + 1.0
        low = [-self.d_bound, -math.pi, -D_DOT_BOUND, -E_DOT_BOUND, 0.0, 0.0]
        high = [self.d_bound, math.pi, D_DOT_BOUND, E_DOT_BOUND, SPEED_BOUND, DESIRED_SPEED_MAX]
        extra_low, extra_high = self._extra_bounds()
        self._has_preview = bool(extra_low)
        self.observation_space = spaces.Box(
            np.array(low + extra_low, dtype=np.float32),
            np.array(high + extra_high, dtype=np.float32),
            dtype=np.float32,
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)

        self.track: CircleTrack | RandomPathTrack = self._make_track()
        self._check_track()
        self._state: State = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._hint = 0
        self._steps = 0
        self._frenet: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
        self.trail: list[tuple[float, float]] = []

    # ---------------------------------------------------------------- task-specific hooks
    def _make_track(self) -> CircleTrack | RandomPathTrack:
        raise NotImplementedError

    def _extra_bounds(self) -> tuple[list[float], list[float]]:
        return [], []

    def _extra_observation(self, x: float, y: float, psi: float) -> list[float]:
        return []

    def _start_arc_length(self) -> float:
        raise NotImplementedError

    def _path_ended(self) -> bool:
        return False

    def _check_track(self) -> None:
        if self.track.curvature_max * self.termination_distance >= 0.95:
            raise ValueError(
                "the road must be wider than its turns: need curvature_max * (road_width / 2 "
                f"+ off_road_margin) < 0.95, got {self.track.curvature_max:.3f} * "
                f"{self.termination_distance:.3f}")

    # ---------------------------------------------------------------- gym API
    @property
    def vehicle_state(self) -> State:
        """Current ``(x, y, psi, v_x, v_y, r)``."""
        return self._state

    @property
    def frenet(self) -> tuple[float, float, float, float]:
        """``(s, d, path_heading, curvature)`` of the car's projection on the centre line."""
        return self._frenet

    def set_vehicle_state(self, state: State) -> tuple[np.ndarray, float, dict[str, Any]]:
        """Place the car at ``state = (x, y, psi, v_x, v_y, r)`` (tests, demonstrations).

        Returns:
            ``(observation, reward, info)`` of that state, as :meth:`step` would report them
            on arriving there (without the termination terms).
        """
        values = tuple(float(v) for v in state)
        if len(values) != 6 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"state must be six finite numbers (x, y, psi, v_x, v_y, r), "
                             f"got {state!r}")
        x, y, psi, v_x, v_y, r = values
        self._state = (x, y, wrap_angle(psi), v_x, v_y, r)
        if isinstance(self.track, RandomPathTrack):
            self._hint = self.track.nearest_index(x, y, 0)
            best = (self.track.xs[self._hint] - x) ** 2 + (self.track.ys[self._hint] - y) ** 2
            for i in range(0, self.track.last_index + 1, 20):  # global search for teleports
                dist = (self.track.xs[i] - x) ** 2 + (self.track.ys[i] - y) ** 2
                if dist < best:
                    best, self._hint = dist, i
        obs, reward, _, info = self._observe()
        return obs, reward, info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: new track (Trajectory) and a random start near the centre line.

        Start: lateral offset U(-d_0/2, d_0/2), heading error U(-0.25, 0.25) rad, forward speed
        U(0, v_d), no side slip, yaw rate v_x * kappa.
        """
        super().reset(seed=seed)
        rng = self.np_random
        self._new_episode_track(rng)
        s0 = self._start_arc_length()
        px, py = self.track.point_at(s0)
        heading = self.track.heading_at(s0)
        offset = float(rng.uniform(-0.5, 0.5)) * self.half_width
        psi = wrap_angle(heading + float(rng.uniform(-0.25, 0.25)))
        v_x = float(rng.uniform(0.0, self.desired_speed))
        x = px - math.sin(heading) * offset
        y = py + math.cos(heading) * offset
        self._state = (x, y, psi, v_x, 0.0, v_x * self.track.curvature_at(s0))
        self._hint = int(s0 / getattr(self.track, "spacing", 1.0))
        self._steps = 0
        self.trail = [(x, y)] if self.render_mode is not None else []
        obs, _, _, info = self._observe()
        return obs, info

    def _new_episode_track(self, rng: np.random.Generator) -> None:
        """Hook: the Trajectory task draws a new path here."""

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply ``[steer, throttle]`` for ``dt`` seconds; returns the gymnasium 5-tuple."""
        steer, throttle = parse_action(action)
        force = throttle * (self._max_drive if throttle >= 0.0 else self._max_brake)
        x, y, psi, v_x, v_y, r = self.model.step(
            self._state, steer * self._max_steer, force, self.dt, self.substeps)
        if not math.isfinite(x + y + psi + v_x + v_y + r):
            raise RuntimeError(f"vehicle state became non-finite: {(x, y, psi, v_x, v_y, r)}")
        self._state = (x, y, (psi + math.pi) % (2.0 * math.pi) - math.pi, v_x, v_y, r)
        self._steps += 1
        if self.render_mode is not None:
            self.trail.append((x, y))
            if len(self.trail) > TRAIL_LENGTH:
                del self.trail[0]

        obs, reward, cost, info = self._observe()
        terminated = self.terminate_off_road and abs(self._frenet[1]) > self.termination_distance
        truncated = self._steps >= self.episode_length or self._path_ended()
        if terminated:
            remaining = self.episode_length - self._steps
            info["reward_termination"] = remaining * reward
            info["cost_termination"] = remaining * cost
            info["cost"] = cost * (1 + remaining)
            reward *= 1 + remaining
            truncated = False
        return obs, reward, terminated, truncated, info

    def _observe(self) -> tuple[np.ndarray, float, float, dict[str, Any]]:
        x, y, psi, v_x, v_y, r = self._state
        s, d, path_heading, curvature, self._hint = self.track.project(x, y, self._hint)
        self._frenet = (s, d, path_heading, curvature)
        e = (psi - path_heading + math.pi) % (2.0 * math.pi) - math.pi
        cos_e = math.cos(e)
        sin_e = math.sin(e)
        d_dot = v_x * sin_e + v_y * cos_e
        e_dot = r - curvature * (v_x * cos_e - v_y * sin_e) / (1.0 - curvature * d)
        speed = math.sqrt(v_x * v_x + v_y * v_y)

        speed_error = speed - self.desired_speed
        reward = -(d * d + self.speed_weight * speed_error * speed_error
                   + (self.heading_weight if abs(e) >= 0.5 * math.pi else 0.0))
        cost = abs(d) - self.half_width
        cost = cost if cost > 0.0 else 0.0

        values = [_clip(d, self.d_bound), e, _clip(d_dot, D_DOT_BOUND),
                  _clip(e_dot, E_DOT_BOUND), speed if speed < SPEED_BOUND else SPEED_BOUND,
                  self.desired_speed]
        if self._has_preview:
            values += self._extra_observation(x, y, psi)
        obs = np.array(values, dtype=np.float32)
        info = {"cost": cost, "cost_off_road": cost, "lateral_distance": d,
                "heading_error": e, "speed": speed}
        return obs, reward, cost, info

    def render(self) -> np.ndarray | None:
        """Top-down RGB image of the road, the car (heading marked) and its recent path."""
        if self.render_mode is None:
            return None
        return render_top_down(self)
