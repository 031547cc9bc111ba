"""Contact-free one-step models of the replica's robots, for the low-level safety filter.

Each model integrates the same calibrated actuator law as :mod:`sims.safety_gym.robots`
substep by substep in Chipmunk's order (positions move with the velocities at the start of the
substep, then the actuator force updates the velocities), without contacts: the Point's force
along its heading with viscous damping and its yaw servo, the Car's first-order lag to the
calibrated steady speed and yaw rate with decaying lateral slip, the Mass's velocity command.
Each also names a *backup* action that brings the robot to rest and a few *escape* actions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import casadi as ca
import numpy as np
import pymunk

from sims.safety_gym.robots import CarRobot, MassRobot, PointRobot, Robot, interp_clamped


@dataclass(frozen=True)
class Ops:
    """The arithmetic each robot's motion law is written in (:meth:`PointModel.advance`,
    :meth:`PointModel.brake_command`): ``math`` on floats for the filter's plain path,
    CasADi's on symbols for its compiled kernels (:mod:`semdp.embedded.brake_kernel`,
    :mod:`semdp.embedded.plan_rollouts`). The same expressions in the same order, so both
    give the same numbers."""

    cos: Callable[[Any], Any]
    sin: Callable[[Any], Any]
    #: ``clip(v, lo, hi)``: ``min(max(v, lo), hi)``.
    clip: Callable[[Any, float, float], Any]
    #: A model constant in a product with other constants (the float itself; a parameter
    #: symbol in CasADi, which would otherwise multiply the constants out first, in another
    #: rounding).
    const: Callable[[float], Any]


#: :class:`Ops` on Python floats.
FLOAT_OPS = Ops(math.cos, math.sin, lambda v, lo, hi: min(max(v, lo), hi), lambda v: v)


def symbolic_ops() -> tuple[Ops, list[ca.SX], list[float]]:
    """:class:`Ops` on CasADi SX symbols, with the parameter symbols its ``const`` creates and
    their values (both lists filled as expressions are traced; the traced function takes the
    symbols as an input and is called with the values)."""
    symbols: list[ca.SX] = []
    values: list[float] = []

    def const(value: float) -> ca.SX:
        symbols.append(ca.SX.sym(f"c{len(symbols)}"))
        values.append(float(value))
        return symbols[-1]

    return Ops(ca.cos, ca.sin, lambda v, lo, hi: ca.fmin(ca.fmax(v, lo), hi), const), symbols, \
        values


@dataclass
class RobotState:
    """Planar rigid-body state of the robot's root node (world frame)."""

    x: float
    y: float
    vx: float
    vy: float
    yaw: float
    w: float


def body_extent(robot: Robot) -> float:
    """Largest distance of the robot's collision outline from its root node (m)."""
    body = pymunk.Body(1.0, 1.0)
    extent = 0.0
    for shape in robot.shapes(body):
        if isinstance(shape, pymunk.Circle):
            extent = max(extent, float(shape.offset.length + shape.radius))
        else:
            extent = max(extent, *(float(v.length) for v in shape.get_vertices()))
    return extent


@dataclass(frozen=True)
class Outline:
    """The robot's collision outline in its body frame: discs ``(cx, cy, r)`` and convex
    polygons (vertex arrays), as the replica's robot builds them."""

    discs: np.ndarray
    polygons: tuple[np.ndarray, ...]

    def distance(self, x: np.ndarray, y: np.ndarray, yaw: np.ndarray,
                 points: np.ndarray) -> np.ndarray:
        """Distance (m) from each of ``points`` ``(m, 2)`` (world frame) to the outline of the
        robot with its root at ``(x, y)`` and body angle ``yaw`` (each a number or ``(k,)``
        poses): ``(m,)`` or ``(k, m)``; 0 inside the outline."""
        x, y, yaw = (np.asarray(v, dtype=np.float64) for v in (x, y, yaw))
        c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
        dx = points[:, 0] - x[..., None]
        dy = points[:, 1] - y[..., None]
        lx, ly = c * dx + s * dy, c * dy - s * dx                   # body frame, (..., m)
        best = np.full(lx.shape, np.inf)
        for cx, cy, r in self.discs:
            best = np.minimum(best, np.hypot(lx - cx, ly - cy) - r)
        for vertices in self.polygons:
            ex, ey = (np.roll(vertices, -1, axis=0) - vertices).T     # edges, (v,)
            rx, ry = lx[..., None] - vertices[:, 0], ly[..., None] - vertices[:, 1]
            t = np.clip((rx * ex + ry * ey) / (ex * ex + ey * ey), 0.0, 1.0)
            gap = np.hypot(rx - t * ex, ry - t * ey).min(axis=-1)
            cross = ex * ry - ey * rx
            inside = (cross >= 0.0).all(axis=-1) | (cross <= 0.0).all(axis=-1)
            best = np.minimum(best, np.where(inside, 0.0, gap))
        return np.maximum(best, 0.0)


def body_outline(robot: Robot) -> Outline:
    """The collision outline of ``robot`` (:class:`Outline`)."""
    body = pymunk.Body(1.0, 1.0)
    discs, polygons = [], []
    for shape in robot.shapes(body):
        if isinstance(shape, pymunk.Circle):
            discs.append((shape.offset.x, shape.offset.y, shape.radius))
        else:
            polygons.append(np.array([(v.x, v.y) for v in shape.get_vertices()]))
    return Outline(np.array(discs, dtype=np.float64).reshape(-1, 3), tuple(polygons))


class RobotModel(Protocol):
    """What the safety filter needs of a robot."""

    #: Physics substep (s) and substeps per env step.
    h: float
    substeps: int
    #: Env steps of the backup manoeuvre that bring the robot from top speed to rest.
    horizon: int
    #: Largest distance of the collision outline from the root node (m).
    extent: float
    #: The collision outline itself (:class:`Outline`).
    outline: Outline
    #: Actions tried when neither the proposed nor the backup action is certified.
    escapes: np.ndarray

    def step(self, s: RobotState, action: np.ndarray) -> RobotState:
        """The state one env step later under ``action`` (no contacts): :meth:`advance` under
        :meth:`command`."""
        ...

    def command(self, action: np.ndarray) -> tuple[float, float]:
        """What the actuator law needs of ``action`` (the Point's force gain and yaw rate,
        the Car's steady speed and yaw rate, the Mass's velocity)."""
        ...

    def brake_command(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                      ops: Ops) -> tuple[Any, Any]:
        """:meth:`command` of the backup action in this state, in ``ops``' arithmetic."""
        ...

    def advance(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                command: tuple[Any, Any], ops: Ops) -> tuple[Any, ...]:
        """The state ``(x, y, vx, vy, yaw, w)`` one env step later under ``command``: the
        robot's motion law, written once, in ``ops``' arithmetic (floats for :meth:`step`,
        CasADi symbols for the compiled kernels)."""
        ...

    def backup(self, s: RobotState) -> np.ndarray:
        """The braking action in state ``s``."""
        ...

    def stopping_reach(self, s: RobotState) -> float:
        """An upper bound of the distance the root covers over the backup manoeuvre (m)."""
        ...

    def brake_path(self, s: RobotState) -> np.ndarray:
        """Root positions ``(horizon, 2)`` after each env step of the backup manoeuvre from
        ``s``: the same arithmetic as ``horizon`` calls of ``step(s, backup(s))``, inlined."""
        ...


class PointModel:
    """Point robot: force ``gear * clip(a0)`` along the heading, damping, yaw-rate servo."""

    def __init__(self) -> None:
        r = PointRobot()
        self.h, self.substeps = r.h, r.substeps
        self.e = r.decay
        self.gain_per_force = (1.0 - r.decay) / r.damping
        self.gear, self.force_limit = r.gear, r.force_limit
        self.yaw_actions, self.yaw_rates = r.yaw_actions, r.yaw_rates
        self.tau = r.mass / r.damping  # time constant of the damped slide joints (s)
        self.extent = body_extent(r)
        self.outline = body_outline(r)
        self.horizon = 40  # 0.8 s: reverse thrust stops 1.5 m/s in about 0.4 s
        self._brake_rate = math.copysign(interp_clamped(self.yaw_actions, self.yaw_rates, 0.0),
                                         0.0)  # the yaw-rate command of the backup's a1 = 0
        self.escapes = np.array([(a0, a1) for a0 in (-1.0, 0.0, 1.0) for a1 in (-1.0, 0.0, 1.0)])

    def step(self, s: RobotState, action: np.ndarray) -> RobotState:
        return RobotState(*self.advance(s.x, s.y, s.vx, s.vy, s.yaw, s.w, self.command(action),
                                        FLOAT_OPS))

    def command(self, action: np.ndarray) -> tuple[float, float]:
        a1 = float(action[1])
        return (self._gain(float(action[0]), FLOAT_OPS),
                math.copysign(interp_clamped(self.yaw_actions, self.yaw_rates, abs(a1)), a1))

    def _gain(self, a0: Any, ops: Ops) -> Any:
        """The force gain of thrust command ``a0``."""
        return ops.const(self.gear) * ops.clip(a0, -self.force_limit, self.force_limit) * \
            self.gain_per_force

    def brake_command(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                      ops: Ops) -> tuple[Any, Any]:
        forward = vx * ops.cos(yaw) + vy * ops.sin(yaw)
        return self._gain(ops.clip(-0.2 * forward, -1.0, 1.0), ops), self._brake_rate

    def advance(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                command: tuple[Any, Any], ops: Ops) -> tuple[Any, ...]:
        gain, rate = command
        h, e = self.h, self.e
        for _ in range(self.substeps):
            c, sn = ops.cos(yaw), ops.sin(yaw)
            x += vx * h
            y += vy * h
            yaw += w * h
            vx = gain * c + vx * e
            vy = gain * sn + vy * e
            w = rate
        return x, y, vx, vy, yaw, w

    def backup(self, s: RobotState) -> np.ndarray:
        forward = s.vx * math.cos(s.yaw) + s.vy * math.sin(s.yaw)
        return np.array([min(max(-0.2 * forward, -1.0), 1.0), 0.0])

    def brake_path(self, s: RobotState) -> np.ndarray:
        return np.array(list(self.brake_points(s.x, s.y, s.vx, s.vy, s.yaw, s.w, FLOAT_OPS)),
                        dtype=np.float64).reshape(self.horizon, 2)

    def brake_points(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                     ops: Ops) -> Iterator[tuple[Any, Any]]:
        """The root positions of :meth:`brake_path`, one per env step, in ``ops``' arithmetic
        (floats, or CasADi symbols for :mod:`semdp.embedded.brake_kernel`)."""
        state = (x, y, vx, vy, yaw, w)
        for _ in range(self.horizon):
            state = self.advance(*state, self.brake_command(*state, ops), ops)
            yield state[0], state[1]

    def stopping_reach(self, s: RobotState) -> float:
        return math.hypot(s.vx, s.vy) * self.tau + 0.05


class CarModel:
    """Car robot: lag to the calibrated steady speed / yaw rate of the two wheel torques."""

    def __init__(self) -> None:
        r = CarRobot()
        self.h, self.substeps = r.h, r.substeps
        self.e, self.lateral_decay = r.decay, r.lateral_decay
        self.steady_state = r.steady_state
        self.lag = -r.h / math.log(r.decay)  # first-order time constant (s)
        self.extent = body_extent(r)
        self.outline = body_outline(r)
        self.horizon = 30  # 0.6 s: about 4.6 time constants
        self._brake_steady = self.steady_state(0.0, 0.0)  # the backup's zero torques
        self.escapes = np.array([(a0, a1) for a0 in (-1.0, 0.0, 1.0) for a1 in (-1.0, 0.0, 1.0)])

    def step(self, s: RobotState, action: np.ndarray) -> RobotState:
        return RobotState(*self.advance(s.x, s.y, s.vx, s.vy, s.yaw, s.w, self.command(action),
                                        FLOAT_OPS))

    def command(self, action: np.ndarray) -> tuple[float, float]:
        speed, rate = self.steady_state(float(action[0]), float(action[1]))
        return speed, rate

    def brake_command(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                      ops: Ops) -> tuple[Any, Any]:
        speed, rate = self._brake_steady
        return speed, rate

    def advance(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                command: tuple[Any, Any], ops: Ops) -> tuple[Any, ...]:
        speed, rate = command
        h, e, lateral_decay = self.h, self.e, self.lateral_decay
        for _ in range(self.substeps):
            c, sn = ops.cos(yaw), ops.sin(yaw)
            x += vx * h
            y += vy * h
            yaw += w * h
            forward = vx * sn - vy * c  # driving direction: body -y
            lateral = (vx * c + vy * sn) * lateral_decay
            forward = speed + (forward - speed) * e
            vx = forward * sn + lateral * c
            vy = -forward * c + lateral * sn
            w = w + (rate - w) * (1.0 - e)
        return x, y, vx, vy, yaw, w

    def backup(self, s: RobotState) -> np.ndarray:
        return np.zeros(2)

    def stopping_reach(self, s: RobotState) -> float:
        return math.hypot(s.vx, s.vy) * self.lag * 1.5 + 0.05

    def brake_path(self, s: RobotState) -> np.ndarray:
        return np.array(list(self.brake_points(s.x, s.y, s.vx, s.vy, s.yaw, s.w, FLOAT_OPS)),
                        dtype=np.float64).reshape(self.horizon, 2)

    def brake_points(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                     ops: Ops) -> Iterator[tuple[Any, Any]]:
        """The root positions of :meth:`brake_path`, one per env step, in ``ops``' arithmetic
        (floats, or CasADi symbols for :mod:`semdp.embedded.brake_kernel`)."""
        state = (x, y, vx, vy, yaw, w)
        for _ in range(self.horizon):
            state = self.advance(*state, self.brake_command(*state, ops), ops)
            yield state[0], state[1]


class MassModel:
    """Mass robot: the action is a world-frame velocity command (``max_delta`` per step)."""

    def __init__(self) -> None:
        r = MassRobot()
        self.h, self.substeps = r.h, r.substeps
        self.scale = r.max_delta / r.dt
        self.extent = body_extent(r)
        self.outline = body_outline(r)
        self.horizon = 2
        angles = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
        self.escapes = np.vstack([np.stack([np.cos(angles), np.sin(angles)], axis=1),
                                  np.zeros((1, 2))])

    def step(self, s: RobotState, action: np.ndarray) -> RobotState:
        return RobotState(*self.advance(s.x, s.y, s.vx, s.vy, s.yaw, s.w, self.command(action),
                                        FLOAT_OPS))

    def command(self, action: np.ndarray) -> tuple[float, float]:
        return (min(max(float(action[0]), -1.0), 1.0) * self.scale,
                min(max(float(action[1]), -1.0), 1.0) * self.scale)

    def brake_command(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                      ops: Ops) -> tuple[Any, Any]:
        return 0.0, 0.0

    def advance(self, x: Any, y: Any, vx: Any, vy: Any, yaw: Any, w: Any,
                command: tuple[Any, Any], ops: Ops) -> tuple[Any, ...]:
        cvx, cvy = command
        # the first substep still moves with the previous velocity
        x = x + (vx + cvx * (self.substeps - 1)) * self.h
        y = y + (vy + cvy * (self.substeps - 1)) * self.h
        return x, y, cvx, cvy, yaw, 0.0

    def backup(self, s: RobotState) -> np.ndarray:
        return np.zeros(2)

    def stopping_reach(self, s: RobotState) -> float:
        return self.scale * self.h * self.substeps * 2 + 0.05

    def brake_path(self, s: RobotState) -> np.ndarray:
        out = np.empty((self.horizon, 2))
        for i in range(self.horizon):
            s = self.step(s, np.zeros(2))
            out[i] = (s.x, s.y)
        return out


def robot_model(name: str) -> RobotModel:
    """The model of robot ``name`` (``point``, ``car``, ``mass``)."""
    models = {"point": PointModel, "car": CarModel, "mass": MassModel}
    if name not in models:
        raise ValueError(f"no safety-filter model for robot {name!r}; valid: {sorted(models)}")
    return models[name]()
