"""Hand-written reference controller: pure pursuit steering + speed P-control (App. A.2).

Used by the tests and ``semdp-bench driving`` to show that the tasks get harder with v_d
(thesis Figs. A.3/A.4): it stays on the road at low speed and slides off at high speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sims.driving.base import DrivingEnv


@dataclass
class PurePursuitController:
    """Pure pursuit on the centre line (from the rear axle) plus feed-forward + P speed control.

    Steering: ``delta = atan(2 L y_t / l^2)`` towards the centre-line point ``lookahead`` metres
    of arc length ahead of the projection (``y_t``: its lateral coordinate in the rear-axle
    frame, ``l``: its distance), with ``lookahead = clip(lookahead_gain * v, min, max)``.
    Speed: ``F = c_drag v_d + m * speed_gain * (v_d - v)``.

    Attributes:
        lookahead_gain: Lookahead time [s].
        lookahead_min: Smallest lookahead [m].
        lookahead_max: Largest lookahead [m].
        speed_gain: Proportional speed gain [1/s].
    """

    lookahead_gain: float = 0.35
    lookahead_min: float = 0.4
    lookahead_max: float = 2.0
    speed_gain: float = 2.0

    def __call__(self, env: DrivingEnv) -> np.ndarray:
        """Action ``[steer, throttle]`` in [-1, 1]^2 for the env's current state."""
        params = env.model.params
        x, y, psi, v_x, v_y, _ = env.vehicle_state
        speed = math.hypot(v_x, v_y)
        lookahead = min(max(self.lookahead_gain * speed, self.lookahead_min), self.lookahead_max)
        target_x, target_y = env.track.point_at(env.frenet[0] + lookahead)
        c, s = math.cos(psi), math.sin(psi)
        rear_x = x - params.cg_to_rear * c
        rear_y = y - params.cg_to_rear * s
        dx, dy = target_x - rear_x, target_y - rear_y
        forward = c * dx + s * dy
        left = c * dy - s * dx
        delta = math.atan2(2.0 * params.wheelbase * left, forward * forward + left * left)
        force = (params.drag_coefficient * env.desired_speed
                 + params.mass * self.speed_gain * (env.desired_speed - speed))
        limit = params.max_drive_force if force >= 0.0 else params.max_brake_force
        steer = max(-1.0, min(1.0, delta / params.max_steer))
        throttle = max(-1.0, min(1.0, force / limit))
        return np.array([steer, throttle], dtype=np.float32)


def run_episode(
    env: DrivingEnv, controller: PurePursuitController, seed: int
) -> dict[str, float]:
    """Run one episode of ``controller`` on ``env`` (unwrapped).

    Returns:
        ``{"return", "cost", "cost_steps", "length", "terminated", "mean_speed"}``.
    """
    env.reset(seed=seed)
    total_reward = total_cost = speed_sum = 0.0
    cost_steps = length = 0
    terminated = truncated = False
    while not (terminated or truncated):
        _, reward, terminated, truncated, info = env.step(controller(env))
        total_reward += reward
        total_cost += info["cost"]
        cost_steps += info["cost"] > 0.0
        speed_sum += info["speed"]
        length += 1
    return {"return": total_reward, "cost": total_cost, "cost_steps": float(cost_steps),
            "length": float(length), "terminated": float(terminated),
            "mean_speed": speed_sum / length}
