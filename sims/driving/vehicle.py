"""Dynamic bicycle model with brush (Fiala) tyres and a friction circle (thesis App. A.2.1).

State ``(x, y, psi, v_x, v_y, r)``: position of the centre of gravity in the world frame [m],
heading [rad], body-frame velocities [m/s] and yaw rate [rad/s]. Inputs: front steering angle
``delta`` [rad] and the rear-axle longitudinal force command ``f_x`` [N] (rear-wheel drive and
brake). Equations (research note ``optim_driving_anchors.md`` §5.1)::

    m (v_x' - r v_y) = F_xr - F_yf sin(delta) - c_drag v_x
    m (v_y' + r v_x) = F_yf cos(delta) + F_yr
    I_z r'           = a F_yf cos(delta) - b F_yr
    x' = v_x cos(psi) - v_y sin(psi),   y' = v_x sin(psi) + v_y cos(psi),   psi' = r

Tyre lateral force (Fiala brush model, one friction coefficient, so the curve is C1 and there
is no force jump at saturation), with ``t = tan(alpha)`` and ``F_max = xi mu F_z``::

    F_y = -C t + C^2 / (3 F_max) |t| t - C^3 / (27 F_max^2) t^3   for |t| < 3 F_max / C
    F_y = -F_max sgn(t)                                            beyond (full sliding)

Combined slip on the driven rear axle derates the lateral capacity by the friction circle,
``xi = sqrt((mu F_z)^2 - F_x^2) / (mu F_z)`` (Kapania's derating; the longitudinal force itself
is clipped to ``mu F_zr``). Loads are static (``m g b / L`` front, ``m g a / L`` rear).

Low speed. Slip angles ``atan((v_y + a r) / v_x)`` are singular and the lateral dynamics stiff
(eigenvalues ~ ``-(C_f + C_r) / (m v_x)``) as the car stops. Below ``blend_speed_low`` the
model is kinematic (rear axle without side slip: ``r -> v_x tan(delta) / L`` and
``v_y -> b r``, reached with the time constant ``kinematic_time_constant``); above
``blend_speed_high`` it is fully dynamic; in between the two right-hand sides are blended
linearly in the speed ``hypot(v_x, v_y)`` (the blend used by e.g. the AMZ driverless
controller). Braking fades out linearly below ``brake_fade_speed`` so that the car stops
instead of reversing.

Integration: classical RK4 with a fixed number of equal substeps per call, written in plain
Python floats (no per-step numpy), so a step is deterministic and fast.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

GRAVITY = 9.81
"""Gravitational acceleration [m/s^2]."""


@dataclass(frozen=True)
class VehicleParams:
    """Physical parameters of a 1/10-scale RC car.

    Defaults: mass, yaw inertia, axle distances and cornering stiffness from r-pad/aa_simulation
    ``envs/model/model_params/rccar.yml`` (the FFAST RC car), friction coefficient 1.37 = that
    project's static coefficient ``mu_s`` (their kinetic ``mu_k = 1.96 > mu_s`` would make the
    force jump at saturation; we use a single coefficient). Research note §5.2.

    Attributes:
        mass: Vehicle mass m [kg].
        yaw_inertia: Yaw moment of inertia I_z [kg m^2].
        cg_to_front: Distance a from the centre of gravity to the front axle [m].
        cg_to_rear: Distance b from the centre of gravity to the rear axle [m].
        cornering_stiffness: Cornering stiffness C_alpha of one axle (front and rear) [N/rad].
        friction: Tyre-road friction coefficient mu [-].
        max_steer: Steering limit |delta| <= max_steer [rad] (aa_simulation: pi/6).
        max_drive_force: Largest rear-axle drive force [N] (action +1).
        max_brake_force: Largest rear-axle brake force [N] (action -1).
        drag_coefficient: Linear longitudinal drag c_drag [N s/m]; 1.0 gives a full-throttle
            top speed of 10 m/s, aa_simulation's speed-command limit.
        brake_fade_speed: Below this forward speed the brake force fades linearly to 0 [m/s].
        blend_speed_low: Speed below which the model is purely kinematic [m/s].
        blend_speed_high: Speed above which the model is purely dynamic [m/s].
        kinematic_time_constant: Relaxation time of v_y and r to their kinematic values [s].
        body_length: Drawn body length [m] (rendering only).
        body_width: Drawn body width [m] (rendering only; aa_simulation track width 0.165 m).
    """

    mass: float = 2.645
    yaw_inertia: float = 0.0558
    cg_to_front: float = 0.137
    cg_to_rear: float = 0.120
    cornering_stiffness: float = 56.4
    friction: float = 1.37
    max_steer: float = math.pi / 6.0
    max_drive_force: float = 10.0
    max_brake_force: float = 10.0
    drag_coefficient: float = 1.0
    brake_fade_speed: float = 0.1
    blend_speed_low: float = 0.25
    blend_speed_high: float = 0.75
    kinematic_time_constant: float = 0.05
    body_length: float = 0.40
    body_width: float = 0.19

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"VehicleParams.{name} must be a finite positive number, "
                                 f"got {value!r}")
        if self.max_steer >= math.pi / 2:
            raise ValueError(f"max_steer must be < pi/2, got {self.max_steer!r}")
        if self.blend_speed_high <= self.blend_speed_low:
            raise ValueError("blend_speed_high must exceed blend_speed_low, got "
                             f"{self.blend_speed_high!r} <= {self.blend_speed_low!r}")

    @property
    def wheelbase(self) -> float:
        """L = a + b [m]."""
        return self.cg_to_front + self.cg_to_rear

    @property
    def front_load(self) -> float:
        """Static normal load on the front axle F_zf = m g b / L [N]."""
        return self.mass * GRAVITY * self.cg_to_rear / self.wheelbase

    @property
    def rear_load(self) -> float:
        """Static normal load on the rear axle F_zr = m g a / L [N]."""
        return self.mass * GRAVITY * self.cg_to_front / self.wheelbase


def fiala_lateral_force(tan_slip: float, cornering_stiffness: float, max_force: float) -> float:
    """Fiala brush-tyre lateral force for one axle (research note §5.1).

    Args:
        tan_slip: tan(alpha) of the slip angle alpha.
        cornering_stiffness: C_alpha [N/rad].
        max_force: Available friction force xi mu F_z [N] (>= 0).

    Returns:
        Lateral force F_y [N]; opposes the slip and saturates at ``max_force`` (C1 curve).
    """
    if max_force <= 0.0:
        return 0.0
    limit = 3.0 * max_force / cornering_stiffness
    if abs(tan_slip) >= limit:
        return -max_force if tan_slip > 0.0 else max_force
    c = cornering_stiffness
    k2 = c * c / (3.0 * max_force)
    k3 = c * c * c / (27.0 * max_force * max_force)
    return tan_slip * (-c + k2 * abs(tan_slip) - k3 * tan_slip * tan_slip)


class BicycleModel:
    """Integrates the blended dynamic/kinematic bicycle model (module docstring).

    Args:
        params: Vehicle parameters.

    The model is stateless: :meth:`step` maps a state tuple to the next one.
    """

    def __init__(self, params: VehicleParams | None = None) -> None:
        self.params = params if params is not None else VehicleParams()
        p = self.params
        self._front_max = p.friction * p.front_load
        self._rear_mu_fz = p.friction * p.rear_load
        self._front_alpha_limit = math.atan(3.0 * self._front_max / p.cornering_stiffness)
        self._front_k2 = p.cornering_stiffness**2 / (3.0 * self._front_max)
        self._front_k3 = p.cornering_stiffness**3 / (27.0 * self._front_max**2)

    def longitudinal_force(self, force_command: float, v_x: float) -> float:
        """Rear-axle force after brake fade and the friction limit |F_x| <= mu F_zr [N]."""
        p = self.params
        if force_command < 0.0:
            fade = v_x / p.brake_fade_speed
            fade = 1.0 if fade > 1.0 else (-1.0 if fade < -1.0 else fade)
            force_command *= fade
        limit = self._rear_mu_fz
        return limit if force_command > limit else (-limit if force_command < -limit
                                                    else force_command)

    def blend_weight(self, v_x: float, v_y: float) -> float:
        """Weight lambda of the dynamic model (0: kinematic, 1: dynamic) at this speed."""
        p = self.params
        speed = math.sqrt(v_x * v_x + v_y * v_y)
        if speed <= p.blend_speed_low:
            return 0.0
        if speed >= p.blend_speed_high:
            return 1.0
        return (speed - p.blend_speed_low) / (p.blend_speed_high - p.blend_speed_low)

    def tyre_forces(
        self, v_x: float, v_y: float, r: float, delta: float, force_command: float
    ) -> dict[str, float]:
        """Tyre quantities of the dynamic model at one state (for tests and diagnostics).

        Returns:
            Dict with slip angles ``alpha_front``/``alpha_rear`` [rad], lateral forces
            ``fy_front``/``fy_rear`` [N], rear ``fx_rear`` [N], and the available lateral
            friction ``fy_front_max``/``fy_rear_max`` (= xi mu F_z) [N].
        """
        p = self.params
        fx = self.longitudinal_force(force_command, v_x)
        vx_abs = max(abs(v_x), 1e-3)
        alpha_front = math.atan((v_y + p.cg_to_front * r) / vx_abs) - delta
        tan_rear = (v_y - p.cg_to_rear * r) / vx_abs
        rear_max = math.sqrt(max(self._rear_mu_fz**2 - fx * fx, 0.0))
        if abs(alpha_front) >= self._front_alpha_limit:
            fy_front = -self._front_max if alpha_front > 0.0 else self._front_max
        else:
            fy_front = fiala_lateral_force(math.tan(alpha_front), p.cornering_stiffness,
                                           self._front_max)
        return {
            "alpha_front": alpha_front,
            "alpha_rear": math.atan(tan_rear),
            "fy_front": fy_front,
            "fy_rear": fiala_lateral_force(tan_rear, p.cornering_stiffness, rear_max),
            "fx_rear": fx,
            "fy_front_max": self._front_max,
            "fy_rear_max": rear_max,
        }

    def _body_rates(
        self,
        v_x: float,
        v_y: float,
        r: float,
        delta: float,
        cos_delta: float,
        sin_delta: float,
        tan_delta: float,
        force_command: float,
    ) -> tuple[float, float, float]:
        """Blended (v_x', v_y', r') at one RK4 stage: :meth:`longitudinal_force`,
        :meth:`tyre_forces` and :meth:`blend_weight` written out in one function (the hot
        path); tests/test_driving_vehicle.py checks them equal."""
        p = self.params
        m = p.mass
        # longitudinal force: brake fade + friction limit (inlined longitudinal_force)
        fx = force_command
        if fx < 0.0:
            fade = v_x / p.brake_fade_speed
            fx *= 1.0 if fade > 1.0 else (-1.0 if fade < -1.0 else fade)
        mu_fz = self._rear_mu_fz
        if fx > mu_fz:
            fx = mu_fz
        elif fx < -mu_fz:
            fx = -mu_fz
        drive = fx - p.drag_coefficient * v_x

        speed = math.sqrt(v_x * v_x + v_y * v_y)
        low = p.blend_speed_low
        if speed <= low:
            lam = 0.0
        elif speed >= p.blend_speed_high:
            lam = 1.0
        else:
            lam = (speed - low) / (p.blend_speed_high - low)

        dvx = dvy = dr = 0.0
        if lam > 0.0:
            a = p.cg_to_front
            b = p.cg_to_rear
            c = p.cornering_stiffness
            vx_abs = v_x if v_x > 1e-3 else (-v_x if v_x < -1e-3 else 1e-3)
            # front axle (undriven, full friction)
            alpha_f = math.atan((v_y + a * r) / vx_abs) - delta
            if alpha_f >= self._front_alpha_limit:
                fyf = -self._front_max
            elif alpha_f <= -self._front_alpha_limit:
                fyf = self._front_max
            else:
                t = math.tan(alpha_f)
                fyf = t * (-c + self._front_k2 * abs(t) - self._front_k3 * t * t)
            # rear axle, derated by the friction circle
            t = (v_y - b * r) / vx_abs
            rear_sq = mu_fz * mu_fz - fx * fx
            if rear_sq <= 0.0:
                fyr = 0.0
            else:
                rear_max = math.sqrt(rear_sq)
                if t >= 3.0 * rear_max / c:
                    fyr = -rear_max
                elif t <= -3.0 * rear_max / c:
                    fyr = rear_max
                else:
                    fyr = t * (-c + c * c / (3.0 * rear_max) * abs(t)
                               - c * c * c / (27.0 * rear_sq) * t * t)
            fyf_cos = fyf * cos_delta
            dvx = lam * ((drive - fyf * sin_delta) / m + r * v_y)
            dvy = lam * ((fyf_cos + fyr) / m - r * v_x)
            dr = lam * (a * fyf_cos - b * fyr) / p.yaw_inertia
        if lam < 1.0:
            kin = 1.0 - lam
            r_kin = v_x * tan_delta / p.wheelbase
            inv_tau = 1.0 / p.kinematic_time_constant
            dvx += kin * drive / m
            dvy += kin * (p.cg_to_rear * r_kin - v_y) * inv_tau
            dr += kin * (r_kin - r) * inv_tau
        return dvx, dvy, dr

    def step(
        self,
        state: tuple[float, float, float, float, float, float],
        delta: float,
        force_command: float,
        dt: float,
        substeps: int,
    ) -> tuple[float, float, float, float, float, float]:
        """Advance ``state`` by ``dt`` with ``substeps`` RK4 substeps (inputs held constant).

        Args:
            state: ``(x, y, psi, v_x, v_y, r)``.
            delta: Steering angle [rad]; clipped to ``+-max_steer``.
            force_command: Rear-axle force command [N] (brake fade and friction limit applied).
            dt: Time step [s] (> 0).
            substeps: Number of RK4 substeps (>= 1).

        Returns:
            The next state tuple.
        """
        max_steer = self.params.max_steer
        delta = max_steer if delta > max_steer else (-max_steer if delta < -max_steer else delta)
        cos_d = math.cos(delta)
        sin_d = math.sin(delta)
        tan_d = sin_d / cos_d
        rates = self._body_rates
        cos = math.cos
        sin = math.sin
        h = dt / substeps
        h2 = 0.5 * h
        x, y, psi, vx, vy, r = state
        for _ in range(substeps):
            c1 = cos(psi)
            s1 = sin(psi)
            ax1, ay1, ar1 = rates(vx, vy, r, delta, cos_d, sin_d, tan_d, force_command)
            px1 = vx * c1 - vy * s1
            py1 = vx * s1 + vy * c1

            vx2 = vx + h2 * ax1
            vy2 = vy + h2 * ay1
            r2 = r + h2 * ar1
            psi2 = psi + h2 * r
            c2 = cos(psi2)
            s2 = sin(psi2)
            ax2, ay2, ar2 = rates(vx2, vy2, r2, delta, cos_d, sin_d, tan_d, force_command)
            px2 = vx2 * c2 - vy2 * s2
            py2 = vx2 * s2 + vy2 * c2

            vx3 = vx + h2 * ax2
            vy3 = vy + h2 * ay2
            r3 = r + h2 * ar2
            psi3 = psi + h2 * r2
            c3 = cos(psi3)
            s3 = sin(psi3)
            ax3, ay3, ar3 = rates(vx3, vy3, r3, delta, cos_d, sin_d, tan_d, force_command)
            px3 = vx3 * c3 - vy3 * s3
            py3 = vx3 * s3 + vy3 * c3

            vx4 = vx + h * ax3
            vy4 = vy + h * ay3
            r4 = r + h * ar3
            psi4 = psi + h * r3
            c4 = cos(psi4)
            s4 = sin(psi4)
            ax4, ay4, ar4 = rates(vx4, vy4, r4, delta, cos_d, sin_d, tan_d, force_command)
            px4 = vx4 * c4 - vy4 * s4
            py4 = vx4 * s4 + vy4 * c4

            h6 = h / 6.0
            x += h6 * (px1 + 2.0 * (px2 + px3) + px4)
            y += h6 * (py1 + 2.0 * (py2 + py3) + py4)
            psi += h6 * (r + 2.0 * (r2 + r3) + r4)
            vx += h6 * (ax1 + 2.0 * (ax2 + ax3) + ax4)
            vy += h6 * (ay1 + 2.0 * (ay2 + ay3) + ay4)
            r += h6 * (ar1 + 2.0 * (ar2 + ar3) + ar4)
        return x, y, psi, vx, vy, r
