"""Robots of the Safety Gym replica: Point, Car and Mass as pymunk bodies (Safety-Gymnasium 1.0.0).

Each robot is a dynamic pymunk body that receives, before every physics substep, the force and
move its velocity to what a calibrated actuator model prescribes for the substep. Chipmunk
integrates that force before its contact solve (setting velocities directly would move the
body before contacts are resolved and let it creep into obstacles), so contacts, pushing and
blocking stay physical.

* **Point**: force ``0.3 * clip(a0, ±0.05)`` N along body +x with viscous damping
  0.01 N·s/m on both slide joints (mass 0.00518879 kg, time constant 0.519 s, 1.5 m/s at
  saturation), integrated exactly per substep. The yaw servo is replaced by its measured
  steady-state curve (dead zone below |a1| ≈ 0.09, 3.0 rad/s at 1.0): MuJoCo's floor-contact
  friction that shapes it has no 2D equivalent, and the measured yaw responds within
  one step.
* **Car**: the measured steady-state speed and yaw rate as functions of the two
  wheel torques (saturating at ±0.02), interpolated over the torque triangle, reached through a
  first-order lag of 0.13 s (fitted to 0.20/0.59/0.76 m/s after 1/5/10 steps). Lateral
  (non-holonomic) velocity decays with 0.02 s. Forward is body −y, as in Safety-Gymnasium.
* **Mass** (thesis §3.6.1): omnidirectional; the action is a world-frame position delta of at
  most 0.03 m per 0.02 s step (1.5 m/s, the Point's top speed), executed as a velocity command;
  it does not rotate (like the unofficial ``mass.xml``: no yaw hinge, Safety-Gymnasium 1.0.0).
"""

from __future__ import annotations

import bisect
import math

import pymunk

#: Collision type shared by every robot shape.
ROBOT_COLLISION_TYPE = 1


def interp_clamped(xs: tuple[float, ...], ys: tuple[float, ...], x: float) -> float:
    """Piecewise-linear interpolation on sorted ``xs`` (clamped at both ends)."""
    if x <= xs[0]:
        return ys[0]
    if x >= xs[-1]:
        return ys[-1]
    j = bisect.bisect_right(xs, x)
    x0, x1 = xs[j - 1], xs[j]
    return ys[j - 1] + (ys[j] - ys[j - 1]) * (x - x0) / (x1 - x0)


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


class Robot:
    """Base class: geometry, actuator model and sensor layout of one robot.

    Attributes:
        name: ``"point"``, ``"car"`` or ``"mass"``.
        dt: env step (s); ``substeps`` pymunk steps of ``dt / substeps`` each.
        scale: factor on every collision shape's coordinates about the body origin (the root
            node): 1.0 is the original shape. Mass, moment of inertia, actuator model and sensors
            stay the nominal ones, so the calibrated speed and yaw responses are unchanged and
            only the footprint (contacts with the box, vases, pillars, gremlins, buttons)
            differs.
        forward_offset: angle of the driving direction relative to body +x (rad).
        sensor_sizes: sensor names and sizes in observation order (Safety-Gymnasium 1.0.0).
    """

    name = "robot"
    dt = 0.02
    substeps = 2
    mass = 1.0
    moment = 1.0
    forward_offset = 0.0
    rotates = True
    sensor_sizes: tuple[tuple[str, int], ...] = (
        ("accelerometer", 3),
        ("velocimeter", 3),
        ("gyro", 3),
        ("magnetometer", 3),
    )

    def __init__(self, scale: float = 1.0) -> None:
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"robot scale must be a positive number, got {scale!r}")
        self.h = self.dt / self.substeps
        self.scale = float(scale)

    def shapes(self, body: pymunk.Body) -> list[pymunk.Shape]:
        """Collision shapes in the body frame."""
        raise NotImplementedError

    def build(self, space: pymunk.Space, x: float, y: float, yaw: float) -> pymunk.Body:
        """Create the body at ``(x, y)`` with body yaw ``yaw`` and add it to ``space``."""
        body = pymunk.Body(self.mass, self.moment if self.rotates else math.inf)
        body.position = (x, y)
        body.angle = yaw if self.rotates else 0.0
        shapes = self.shapes(body)
        for shape in shapes:
            shape.collision_type = ROBOT_COLLISION_TYPE
            shape.friction = 1.0
            shape.elasticity = 0.0
        space.add(body, *shapes)
        self.reset_state()
        return body

    def reset_state(self) -> None:
        """Reset internal actuator state (called on build)."""

    def set_action(self, a0: float, a1: float) -> None:
        """Latch a clipped action (both components already in [-1, 1])."""
        raise NotImplementedError

    def substep(self, body: pymunk.Body) -> tuple[float, float]:
        """Set force/torque for the next pymunk substep of length ``h``.

        Returns:
            The body velocity read before the substep (the env's accelerometer uses it).
        """
        raise NotImplementedError

    def extra_sensors(self, body: pymunk.Body) -> list[float]:
        """Robot-specific sensors appended after the magnetometer (Car only)."""
        return []

    def reset_extra_sensors(self) -> list[float]:
        """Robot-specific sensors at rest."""
        return []


def _box_poly(
    body: pymunk.Body, x0: float, y0: float, x1: float, y1: float, scale: float = 1.0
) -> pymunk.Poly:
    """Axis-aligned box [x0, x1] x [y0, y1] in the body frame, scaled about the body origin."""
    x0, y0, x1, y1 = x0 * scale, y0 * scale, x1 * scale, y1 * scale
    return pymunk.Poly(body, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)])


class PointRobot(Robot):
    """Safety-Gymnasium's Point: forward force + yaw servo, mass 0.00518879 kg."""

    name = "point"
    dt = 0.02
    substeps = 2
    mass = 0.00518879
    moment = 2.842e-5
    damping = 0.01
    gear = 0.3
    force_limit = 0.05
    radius = 0.1
    #: Measured steady yaw rate (rad/s) vs |a1| (Safety-Gymnasium table; dead zone below ≈ 0.09).
    yaw_actions = (0.0, 0.09, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
    yaw_rates = (0.0, 0.0, 0.033, 0.264, 0.495, 0.78, 1.0, 1.35, 1.69, 2.06, 2.44, 2.81, 3.0)

    def __init__(self, scale: float = 1.0) -> None:
        super().__init__(scale)
        self.decay = math.exp(-self.h * self.damping / self.mass)
        self.force = 0.0
        self.yaw_rate = 0.0

    def shapes(self, body: pymunk.Body) -> list[pymunk.Shape]:
        """Sphere r=0.1 at the origin plus the 0.1 x 0.1 nose box spanning x in [0.05, 0.15]
        (times ``scale``)."""
        s = self.scale
        return [pymunk.Circle(body, self.radius * s), _box_poly(body, 0.05, -0.05, 0.15, 0.05, s)]

    def reset_state(self) -> None:
        self.force = 0.0
        self.yaw_rate = 0.0

    def set_action(self, a0: float, a1: float) -> None:
        self.force = self.gear * _clip(a0, -self.force_limit, self.force_limit)
        rate = interp_clamped(self.yaw_actions, self.yaw_rates, abs(a1))
        self.yaw_rate = rate if a1 >= 0.0 else -rate

    def substep(self, body: pymunk.Body) -> tuple[float, float]:
        vx, vy = body.velocity
        yaw = body.angle
        e = self.decay
        gain = self.force / self.damping * (1.0 - e)
        k = self.mass / self.h
        body.force = (k * (gain * math.cos(yaw) - vx * (1.0 - e)),
                      k * (gain * math.sin(yaw) - vy * (1.0 - e)))  # fmt: skip
        body.torque = self.moment / self.h * (self.yaw_rate - body.angular_velocity)
        return vx, vy


class CarRobot(Robot):
    """Safety Gym's Car: two driven wheels, forward = body −y, total 0.030445 kg."""

    name = "car"
    dt = 0.04
    substeps = 4
    mass = 0.030445
    moment = 3.648e-4
    forward_offset = -math.pi / 2
    torque_limit = 0.02
    lag_s = 0.13
    lateral_lag_s = 0.02
    caster_offset = 0.1  # the caster ball sits at body (0, -0.1)
    caster_radius = 0.05
    sensor_sizes = (*Robot.sensor_sizes, ("ballangvel_rear", 3), ("ballquat_rear", 9))
    #: Measured steady states. Drive level r = |s| + |d| with s, d the mean and half
    #: difference of the normalised torques; t = |d| / r the turning share.
    radial_levels = (0.0, 0.125, 0.25, 0.5, 0.75, 1.0)
    straight_speeds = (0.0, 0.084, 0.168, 0.372, 0.611, 0.775)
    spin_rates = (0.0, 0.355, 0.637, 0.879, 1.065, 1.321)
    edge_shares = (0.0, 0.25, 0.5, 0.75, 1.0)
    edge_speeds = (0.775, 0.457, 0.144, 0.066, 0.0)
    edge_rates = (0.0, 0.379, 0.623, 1.025, 1.321)
    reverse_factor = 0.761 / 0.775  # measured: full reverse is 1.8% slower than full forward

    def __init__(self, scale: float = 1.0) -> None:
        super().__init__(scale)
        self.decay = math.exp(-self.h / self.lag_s)
        self.lateral_decay = math.exp(-self.h / self.lateral_lag_s)
        self.target_speed = 0.0
        self.target_rate = 0.0
        self.ball = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]

    def shapes(self, body: pymunk.Body) -> list[pymunk.Shape]:
        """Chassis, bumpers and wheels: footprint x in [−0.155, 0.155], y in [−0.175, 0.16]
        (times ``scale``; the caster-ball sensors keep the nominal ball)."""
        s = self.scale
        return [
            _box_poly(body, -0.1, -0.1, 0.1, 0.1, s),
            _box_poly(body, -0.1, 0.14, 0.1, 0.16, s),
            _box_poly(body, -0.05, -0.175, 0.05, -0.1, s),
            _box_poly(body, -0.155, 0.05, -0.105, 0.15, s),
            _box_poly(body, 0.105, 0.05, 0.155, 0.15, s),
        ]

    def reset_state(self) -> None:
        self.target_speed = 0.0
        self.target_rate = 0.0
        self.ball = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]

    @classmethod
    def steady_state(cls, a0: float, a1: float) -> tuple[float, float]:
        """Calibrated steady forward speed (m/s) and yaw rate (rad/s) for wheel torques."""
        u0 = _clip(a0, -cls.torque_limit, cls.torque_limit) / cls.torque_limit
        u1 = _clip(a1, -cls.torque_limit, cls.torque_limit) / cls.torque_limit
        s = 0.5 * (u0 + u1)
        d = 0.5 * (u0 - u1)
        level = abs(s) + abs(d)
        if level <= 0.0:
            return 0.0, 0.0
        share = abs(d) / level
        shape = (1.0 - share) * interp_clamped(
            cls.radial_levels, cls.straight_speeds, level
        ) / cls.straight_speeds[-1] + share * interp_clamped(
            cls.radial_levels, cls.spin_rates, level
        ) / cls.spin_rates[-1]
        speed = interp_clamped(cls.edge_shares, cls.edge_speeds, share) * shape
        rate = interp_clamped(cls.edge_shares, cls.edge_rates, share) * shape
        if s < 0.0:
            speed *= cls.reverse_factor
        return math.copysign(speed, s), math.copysign(rate, d)

    def set_action(self, a0: float, a1: float) -> None:
        self.target_speed, self.target_rate = self.steady_state(a0, a1)

    def substep(self, body: pymunk.Body) -> tuple[float, float]:
        vx, vy = body.velocity
        yaw = body.angle
        c, s = math.cos(yaw), math.sin(yaw)
        fx, fy = s, -c  # body -y in world
        forward = vx * fx + vy * fy
        lateral = (vx * c + vy * s) * self.lateral_decay
        e = self.decay
        forward = self.target_speed + (forward - self.target_speed) * e
        k = self.mass / self.h
        body.force = (k * (forward * fx + lateral * c - vx), k * (forward * fy + lateral * s - vy))
        w = body.angular_velocity
        body.torque = self.moment / self.h * (self.target_rate - w) * (1.0 - e)
        return vx, vy

    def extra_sensors(self, body: pymunk.Body) -> list[float]:
        """2D equivalents of ``ballangvel_rear`` (3) and ``ballquat_rear`` (9, a 3x3 matrix).

        The caster ball at body (0, −0.1), r = 0.05, is assumed to roll without slipping: its
        angular velocity relative to the chassis follows from the caster's ground velocity, and
        its orientation relative to the chassis is integrated over the step (Rodrigues).
        """
        vx, vy = body.velocity
        w = body.angular_velocity
        yaw = body.angle
        c, s = math.cos(yaw), math.sin(yaw)
        rx, ry = self.caster_offset * s, -self.caster_offset * c
        cvx, cvy = vx - w * ry, vy + w * rx
        # rolling: Omega x (0, 0, r) = v  ->  Omega = (-vy, vx, 0) / r  (world); to chassis frame
        ox_w, oy_w = -cvy / self.caster_radius, cvx / self.caster_radius
        ox, oy = c * ox_w + s * oy_w, c * oy_w - s * ox_w
        ball = self.ball
        angle = math.hypot(ox, oy) * self.dt
        if angle > 0.0:
            kx, ky = ox * self.dt / angle, oy * self.dt / angle
            sa, ca = math.sin(angle), 1.0 - math.cos(angle)
            # R = I + sin K + (1 - cos) K^2 for axis (kx, ky, 0)
            rot = (
                1.0 - ca * ky * ky, ca * kx * ky, sa * ky,
                ca * kx * ky, 1.0 - ca * kx * kx, -sa * kx,
                -sa * ky, sa * kx, 1.0 - ca * (kx * kx + ky * ky),
            )  # fmt: skip
            ball = [
                rot[3 * i] * ball[j] + rot[3 * i + 1] * ball[3 + j] + rot[3 * i + 2] * ball[6 + j]
                for i in range(3)
                for j in range(3)
            ]
            self.ball = ball
        # angular velocity in the ball (child) frame: R^T omega
        angvel = [ball[j] * ox + ball[3 + j] * oy for j in range(3)]
        return angvel + ball

    def reset_extra_sensors(self) -> list[float]:
        return [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]


class MassRobot(Robot):
    """The thesis' omnidirectional Mass robot (§3.6.1): action = world-frame position delta."""

    name = "mass"
    dt = 0.02
    substeps = 2
    mass = 0.0041888  # the Point's sphere
    radius = 0.1
    max_delta = 0.03  # metres per env step at |a| = 1
    rotates = False

    def __init__(self, scale: float = 1.0) -> None:
        super().__init__(scale)
        self.vx = 0.0
        self.vy = 0.0

    def shapes(self, body: pymunk.Body) -> list[pymunk.Shape]:
        """A disc of radius 0.1 (the Point's sphere without the nose; times ``scale``)."""
        return [pymunk.Circle(body, self.radius * self.scale)]

    def reset_state(self) -> None:
        self.vx = 0.0
        self.vy = 0.0

    def set_action(self, a0: float, a1: float) -> None:
        scale = self.max_delta / self.dt
        self.vx = a0 * scale
        self.vy = a1 * scale

    def substep(self, body: pymunk.Body) -> tuple[float, float]:
        vx, vy = body.velocity
        k = self.mass / self.h
        body.force = (k * (self.vx - vx), k * (self.vy - vy))
        return vx, vy


ROBOT_CLASSES: dict[str, type[Robot]] = {
    "point": PointRobot,
    "car": CarRobot,
    "mass": MassRobot,
}
