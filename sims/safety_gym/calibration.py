"""Robot response measurements against the tables measured in Safety-Gymnasium 1.0.0 (the
constants below; docs/simulators.md, "Robots and calibration").

Each measurement drives a robot alone (Goal level 0, goal planted far away) with a constant
action, as measured in Safety-Gymnasium: average over the last 100 of 400 (Point) or 300 (Car)
env steps. :func:`calibration_table` returns rows ``(quantity, action, ours, spec, rel_error)``.
"""

from __future__ import annotations

import numpy as np

from sims.safety_gym.env import SafetyGymEnv

#: Safety-Gymnasium 1.0.0: Point steady speed (m/s) vs a0 with a1 = 0.
POINT_SPEED = {0.005: 0.150, 0.01: 0.300, 0.02: 0.600, 0.03: 0.900, 0.04: 1.200, 0.05: 1.500}
#: Safety-Gymnasium 1.0.0: Point speed after n steps at saturation.
POINT_RISE = {1: 0.057, 5: 0.263, 10: 0.479, 25: 0.927, 50: 1.281}
#: Safety-Gymnasium 1.0.0: Point yaw rate (rad/s) vs a1 with a0 = 0 (0 inside the dead zone).
POINT_YAW = {
    0.05: 0.0, 0.075: 0.0, 0.1: 0.033, 0.15: 0.264, 0.2: 0.495, 0.3: 0.78, 0.4: 1.0,
    0.5: 1.35, 0.6: 1.69, 0.7: 2.06, 0.8: 2.44, 0.9: 2.81, 1.0: 3.0,
}  # fmt: skip
#: Safety-Gymnasium 1.0.0: combined actions -> (speed, yaw rate).
POINT_COMBINED = {(0.05, 1.0): (0.86, 2.97), (0.05, 0.5): (1.24, 1.34), (0.05, 0.2): (1.45, 0.50)}
#: Safety-Gymnasium 1.0.0: Car (speed, yaw rate) vs wheel torques.
CAR_STEADY = {
    (0.0025, 0.0025): (0.084, 0.0), (0.005, 0.005): (0.168, 0.0), (0.01, 0.01): (0.372, 0.0),
    (0.015, 0.015): (0.611, 0.0), (0.02, 0.02): (0.775, 0.0), (-0.02, -0.02): (0.761, 0.0),
    (0.02, 0.01): (0.457, 0.379), (0.02, 0.0): (0.144, 0.623), (0.02, -0.01): (0.066, 1.025),
    (0.0025, -0.0025): (0.0, 0.355), (0.005, -0.005): (0.0, 0.637), (0.01, -0.01): (0.0, 0.879),
    (0.015, -0.015): (0.0, 1.065), (0.02, -0.02): (0.0, 1.321),
}  # fmt: skip
#: Safety-Gymnasium 1.0.0: Car speed after n steps at saturation.
CAR_RISE = {1: 0.20, 5: 0.59, 10: 0.76}


def _robot_env(robot: str) -> SafetyGymEnv:
    env = SafetyGymEnv(robot=robot, task="goal", level=0)
    env.reset(seed=11, options={"layout": {"agent": (0.0, 0.0), "agent_yaw": 0.0,
                                           "goal": (500.0, 500.0)}})  # fmt: skip
    return env


def steady_response(
    robot: str, action: tuple[float, float], steps: int = 400, window: int = 100
) -> tuple[float, float]:
    """Mean speed (m/s) and yaw rate (rad/s) over the last ``window`` of ``steps`` steps."""
    env = _robot_env(robot)
    speeds, yaws = [], []
    for k in range(steps):
        env.step(action)
        if k >= steps - window:
            speeds.append(float(np.linalg.norm(env.robot_velocity)))
            yaws.append(env.body.angular_velocity)
    return float(np.mean(speeds)), float(np.mean(yaws))


def speed_after(robot: str, action: tuple[float, float], steps: int) -> float:
    """Speed after ``steps`` env steps from rest."""
    env = _robot_env(robot)
    for _ in range(steps):
        env.step(action)
    return float(np.linalg.norm(env.robot_velocity))


def _row(quantity: str, action: object, ours: float, spec: float) -> tuple:
    err = abs(ours - spec) / abs(spec) if spec else abs(ours - spec)
    return quantity, str(action), ours, spec, err


def calibration_table() -> list[tuple[str, str, float, float, float]]:
    """Ours vs Safety-Gymnasium's measured values; ``rel_error`` is absolute where theirs is 0."""
    rows = []
    for a0, spec in POINT_SPEED.items():
        rows.append(_row("Point speed", (a0, 0.0), steady_response("point", (a0, 0.0))[0], spec))
    for n, spec in POINT_RISE.items():
        rows.append(_row(f"Point speed after {n} steps", (0.05, 0.0),
                         speed_after("point", (0.05, 0.0), n), spec))  # fmt: skip
    for a1, spec in POINT_YAW.items():
        rows.append(_row("Point yaw rate", (0.0, a1), steady_response("point", (0.0, a1))[1], spec))
    for action, (v, w) in POINT_COMBINED.items():
        ours_v, ours_w = steady_response("point", action)
        rows.append(_row("Point speed", action, ours_v, v))
        rows.append(_row("Point yaw rate", action, ours_w, w))
    for action, (v, w) in CAR_STEADY.items():
        ours_v, ours_w = steady_response("car", action, steps=300)
        if v or not w:
            rows.append(_row("Car speed", action, ours_v, v))
        if w:
            rows.append(_row("Car yaw rate", action, ours_w, w))
    for n, spec in CAR_RISE.items():
        rows.append(_row(f"Car speed after {n} steps", (0.02, 0.02),
                         speed_after("car", (0.02, 0.02), n), spec))  # fmt: skip
    return rows


def format_table(rows: list[tuple[str, str, float, float, float]]) -> str:
    """Markdown table of :func:`calibration_table` rows."""
    lines = ["| quantity | action | ours | spec | error |", "|---|---|---|---|---|"]
    for quantity, action, ours, spec, err in rows:
        err_txt = f"{100 * err:.1f}%" if spec else f"{err:.3f} abs"
        lines.append(f"| {quantity} | {action} | {ours:.3f} | {spec:.3f} | {err_txt} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    print(format_table(calibration_table()))
