"""Many short plans of one robot rolled out at once: each plan holds one action for some
steps, then brakes (the models' ``backup``), optionally after a common first action.

The same contact-free laws as :mod:`semdp.embedded.robot_models` (``step`` and ``backup``,
substep by substep), on numpy arrays with one element per plan: the moving-gremlin
certificate (:mod:`semdp.embedded.moving_certificate`) tries dozens of plans at every step
it is needed. ``model.step`` stays the definition; tests/test_moving_gremlins.py checks each
rollout against it plan by plan.
"""

from __future__ import annotations

import numpy as np

from semdp.embedded.robot_models import CarModel, MassModel, PointModel, RobotModel, RobotState


def rollout(model: RobotModel, state: RobotState, first: np.ndarray | None,
            actions: np.ndarray, holds: np.ndarray, steps: int, with_yaw: bool = False
            ) -> np.ndarray:
    """Root positions ``(n, steps, 2)`` after each env step of ``n`` plans from ``state``:
    ``first`` (if given) for one step, then ``actions[i]`` for ``holds[i]`` steps, then the
    backup until ``steps`` steps have passed. ``with_yaw``: poses ``(n, steps, 3)``, the
    heading after each step too."""
    actions = np.asarray(actions, dtype=np.float64).reshape(-1, 2)
    holds = np.asarray(holds).reshape(-1)
    n = len(actions)
    x, y, vx, vy, yaw, w = (np.full(n, float(v)) for v in (
        state.x, state.y, state.vx, state.vy, state.yaw, state.w))
    law = _LAWS[type(model)](model, actions)
    out = np.empty((n, steps, 3 if with_yaw else 2))
    offset = 0 if first is None else 1
    for k in range(steps):
        if k < offset:
            command = law.command_of(np.broadcast_to(np.asarray(first, dtype=np.float64), (n, 2)))
        else:
            command = law.held_or_backup(k - offset < holds, x, y, vx, vy, yaw, w)
        x, y, vx, vy, yaw, w = law.step(command, x, y, vx, vy, yaw, w)
        out[:, k, 0], out[:, k, 1] = x, y
        if with_yaw:
            out[:, k, 2] = yaw
    return out


class _PointLaw:
    """:class:`PointModel`'s ``step`` and ``backup`` on arrays."""

    def __init__(self, model: PointModel, actions: np.ndarray) -> None:
        self.m = model
        self.held = self.command_of(actions)

    def command_of(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = self.m
        force = m.gear * np.clip(actions[:, 0], -m.force_limit, m.force_limit)
        rate = np.copysign(np.interp(np.abs(actions[:, 1]), m.yaw_actions, m.yaw_rates),
                           actions[:, 1])
        return force * m.gain_per_force, rate

    def held_or_backup(self, holding: np.ndarray, x: np.ndarray, y: np.ndarray,
                       vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, w: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        m = self.m
        forward = vx * np.cos(yaw) + vy * np.sin(yaw)
        a0 = np.minimum(np.maximum(-0.2 * forward, -1.0), 1.0)               # the backup's
        gain = m.gear * np.minimum(np.maximum(a0, -m.force_limit), m.force_limit) \
            * m.gain_per_force
        return np.where(holding, self.held[0], gain), np.where(holding, self.held[1],
                                                               m._brake_rate)

    def step(self, command: tuple[np.ndarray, np.ndarray], x: np.ndarray, y: np.ndarray,
             vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, w: np.ndarray
             ) -> tuple[np.ndarray, ...]:
        m = self.m
        gain, rate = command
        for _ in range(m.substeps):
            c, sn = np.cos(yaw), np.sin(yaw)
            x = x + vx * m.h
            y = y + vy * m.h
            yaw = yaw + w * m.h
            vx = gain * c + vx * m.e
            vy = gain * sn + vy * m.e
            w = rate
        return x, y, vx, vy, yaw, w


class _CarLaw:
    """:class:`CarModel`'s ``step`` and ``backup`` (zero torques) on arrays."""

    def __init__(self, model: CarModel, actions: np.ndarray) -> None:
        self.m = model
        self.held = self.command_of(actions)
        self.brake = self.command_of(np.zeros((len(actions), 2)))

    def command_of(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        steady = np.array([self.m.steady_state(float(a0), float(a1)) for a0, a1 in actions])
        return steady[:, 0], steady[:, 1]

    def held_or_backup(self, holding: np.ndarray, *state: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        return (np.where(holding, self.held[0], self.brake[0]),
                np.where(holding, self.held[1], self.brake[1]))

    def step(self, command: tuple[np.ndarray, np.ndarray], x: np.ndarray, y: np.ndarray,
             vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, w: np.ndarray
             ) -> tuple[np.ndarray, ...]:
        m = self.m
        speed, rate = command
        for _ in range(m.substeps):
            c, sn = np.cos(yaw), np.sin(yaw)
            x = x + vx * m.h
            y = y + vy * m.h
            yaw = yaw + w * m.h
            forward = vx * sn - vy * c
            lateral = (vx * c + vy * sn) * m.lateral_decay
            forward = speed + (forward - speed) * m.e
            vx = forward * sn + lateral * c
            vy = -forward * c + lateral * sn
            w = w + (rate - w) * (1.0 - m.e)
        return x, y, vx, vy, yaw, w


class _MassLaw:
    """:class:`MassModel`'s ``step`` and ``backup`` (zero velocity) on arrays."""

    def __init__(self, model: MassModel, actions: np.ndarray) -> None:
        self.m = model
        self.held = self.command_of(actions)

    def command_of(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        velocity = np.clip(actions, -1.0, 1.0) * self.m.scale
        return velocity[:, 0], velocity[:, 1]

    def held_or_backup(self, holding: np.ndarray, *state: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        return np.where(holding, self.held[0], 0.0), np.where(holding, self.held[1], 0.0)

    def step(self, command: tuple[np.ndarray, np.ndarray], x: np.ndarray, y: np.ndarray,
             vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, w: np.ndarray
             ) -> tuple[np.ndarray, ...]:
        m = self.m
        cvx, cvy = command
        x = x + (vx + cvx * (m.substeps - 1)) * m.h
        y = y + (vy + cvy * (m.substeps - 1)) * m.h
        return x, y, cvx, cvy, yaw, np.zeros_like(w)


_LAWS = {PointModel: _PointLaw, CarModel: _CarLaw, MassModel: _MassLaw}
