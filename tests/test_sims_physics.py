"""Safety Gym replica physics: calibration, rewards, costs, goals, gremlins, no tunnelling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sims.safety_gym import SafetyGymEnv
from sims.safety_gym.calibration import calibration_table, speed_after, steady_response


def _env(robot: str, task: str, level: int, **layout) -> SafetyGymEnv:
    env = SafetyGymEnv(robot, task, level)
    env.reset(seed=0, options={"layout": layout})
    return env


# ------------------------------------------------------------------ calibration (Safety-Gymnasium)
@pytest.mark.parametrize(
    ("robot", "action", "speed", "yaw_rate"),
    [
        ("point", (0.05, 0.0), 1.5, 0.0),
        ("point", (1.0, 0.0), 1.5, 0.0),  # saturates at |a0| >= 0.05
        ("point", (0.02, 0.0), 0.6, 0.0),
        ("point", (0.0, 1.0), 0.0, 3.0),
        ("point", (0.0, 0.5), 0.0, 1.35),
        ("point", (0.05, 0.5), 1.24, 1.34),
        ("point", (0.05, 1.0), 0.86, 2.97),
        ("car", (0.02, 0.02), 0.775, 0.0),
        ("car", (0.02, -0.02), 0.0, 1.321),
        ("car", (0.02, 0.0), 0.144, 0.623),
    ],
)
def test_calibration_steady_response_within_10_percent(robot, action, speed, yaw_rate) -> None:
    steps = 400 if robot == "point" else 300
    ours_speed, ours_yaw = steady_response(robot, action, steps=steps)
    assert ours_speed == pytest.approx(speed, rel=0.10, abs=0.05)
    assert ours_yaw == pytest.approx(yaw_rate, rel=0.10, abs=1e-6)


def test_calibration_point_yaw_dead_zone_and_time_constant() -> None:
    assert steady_response("point", (0.0, 0.075))[1] == 0.0
    assert steady_response("point", (0.0, -0.2))[1] == pytest.approx(-0.495, rel=0.1)
    # m dv/dt = F - c v with tau = m / c = 0.519 s: 0.479 m/s after 10 steps of 0.02 s
    assert speed_after("point", (1.0, 0.0), 10) == pytest.approx(0.479, rel=0.05)
    assert speed_after("car", (1.0, 1.0), 5) == pytest.approx(0.59, rel=0.10)


def test_calibration_table_every_entry_within_10_percent() -> None:
    for quantity, action, ours, spec, err in calibration_table():
        if spec:
            assert err <= 0.10, (quantity, action, ours, spec)
        else:
            assert abs(ours) <= 0.02, (quantity, action, ours)


def test_mass_moves_by_the_commanded_position_delta() -> None:
    env = _env("mass", "goal", 0, agent=(0.0, 0.0), goal=(50.0, 50.0))
    for _ in range(10):
        env.step((0.5, -1.0))
    start = env.robot_position
    env.step((0.5, -1.0))
    np.testing.assert_allclose(env.robot_position - start, [0.015, -0.03], atol=1e-9)
    assert env.robot_heading == 0.0


# ------------------------------------------------------------------ cost (Safety-Gymnasium 1.0.0)
def test_hazard_cost_switches_on_at_the_expected_step() -> None:
    """The Mass drives +x at 0.03 m/step; pymunk moves a body with the velocity of the previous
    substep, so after n steps x = x0 + 0.03 n - 0.015 (one 0.01 s substep of lag). From
    x0 = -1 the root enters the r = 0.2 hazard at the origin (x > -0.2) at step 28 and leaves
    it (x >= 0.2) at step 41."""
    env = _env("mass", "goal", 1, agent=(-1.0, 0.0), goal=(50.0, 50.0), hazards=[(0.0, 0.0)],
               vases=[])  # fmt: skip
    costs = [env.step((1.0, 0.0))[4]["cost"] for _ in range(45)]
    assert costs[:27] == [0.0] * 27
    assert costs[27:40] == [1.0] * 13
    assert costs[40:] == [0.0] * 5


def test_pillar_and_vase_contact_costs_only_at_level_2() -> None:
    for level, expected in ((1, 0.0), (2, 1.0)):
        env = _env("point", "push", level, agent=(-1.0, 0.0), agent_yaw=0.0, goal=(50, 50),
                   hazards=[], pillars=[(0.0, 0.0)], push_box=(1.2, 1.2))  # fmt: skip
        costs = [env.step((1.0, 0.0))[4]["cost"] for _ in range(80)]
        assert max(costs) == expected
        env = _env("point", "goal", level, agent=(-1.0, 0.0), agent_yaw=0.0, goal=(50, 50),
                   hazards=[], vases=[(0.0, 0.0)])  # fmt: skip
        infos = [env.step((1.0, 0.0))[4] for _ in range(80)]
        assert max(i["cost"] for i in infos) == expected
        if level == 2:
            assert max(i["cost_vases_contact"] for i in infos) == 1.0


@pytest.mark.parametrize(("robot", "reach", "action"), [("mass", 0.1, (0.2, 0.0)),
                                                       ("point", 0.15, (0.01, 0.0))])  # fmt: skip
@pytest.mark.parametrize("scale", [1.0, 1.5])
def test_pillar_contact_starts_at_pillar_radius_plus_scaled_robot_reach(robot, reach, action,
                                                                         scale) -> None:
    """Driving slowly (≤ 6 mm/step) at a planted pillar, the contact cost switches on when the
    centre distance reaches pillar radius + the robot's reach along its heading (Mass: disc
    radius 0.1; Point: nose tip 0.15), both times ``robot_scale``."""
    env = SafetyGymEnv(robot, "push", 2, sizes={"robot_scale": scale})
    env.reset(seed=0, options={"layout": {
        "agent": (-1.0, 0.0), "agent_yaw": 0.0, "goal": (50, 50), "hazards": [],
        "pillars": [(0.0, 0.0)], "push_box": (1.2, 1.2)}})  # fmt: skip
    for _ in range(400):
        if env.step(action)[4]["cost_pillars"]:
            break
    else:
        pytest.fail("never touched the pillar")
    distance = float(np.linalg.norm(env.robot_position))
    assert distance == pytest.approx(0.2 + reach * scale, abs=0.01)


# ------------------------------------------------------------------ rewards (Safety-Gymnasium)
@pytest.mark.parametrize(("robot", "action", "yaw"), [("point", (1.0, 0.0), 0.0),
                                                     ("car", (1.0, 1.0), math.pi / 2),
                                                     ("mass", (1.0, 0.0), 0.0)])  # fmt: skip
def test_scripted_push_moves_box_to_goal_with_positive_reward(robot, action, yaw) -> None:
    env = _env(robot, "push", 1, agent=(-1.2, 0.0), agent_yaw=yaw, push_box=(-0.5, 0.0),
               goal=(0.9, 0.0), hazards=[], pillars=[])  # fmt: skip
    box0 = env.box_position
    rewards, met_at = [], None
    for k in range(150):
        _, reward, _, _, info = env.step(action)
        rewards.append(reward)
        if info["goal_met"]:
            met_at = k
            break
    assert met_at is not None and env.box_position[0] > box0[0] + 0.9
    assert rewards[-1] > 1.0  # the goal bonus
    assert sum(r > 0 for r in rewards[:-1]) >= 0.9 * (len(rewards) - 1)


def test_push_reward_telescopes_to_the_3d_distance_decrease() -> None:
    env = _env("point", "push", 1, agent=(-1.2, 0.0), agent_yaw=0.0, push_box=(-0.5, 0.1),
               goal=(1.3, 1.3), hazards=[], pillars=[])  # fmt: skip

    def potential() -> float:
        r, b, g = env.robot_position, env.box_position, env.goal_position
        d_ab = math.sqrt(np.sum((b - r) ** 2) + (0.2 - 0.1) ** 2)
        d_bg = math.sqrt(np.sum((b - g) ** 2) + (0.2 - 0.16) ** 2)
        return d_ab + d_bg

    start = potential()
    total = sum(env.step((1.0, 0.05))[1] for _ in range(40))
    assert total == pytest.approx(start - potential(), abs=1e-9)
    assert total > 0.0


def test_goal_bonus_then_resample_and_episode_continues() -> None:
    env = _env("mass", "goal", 1, agent=(-0.6, 0.0), goal=(0.0, 0.0), hazards=[], vases=[])
    met_at = None
    for step in range(40):
        _, reward, terminated, truncated, info = env.step((1.0, 0.0))
        if info["goal_met"]:
            met_at = step
            break
    # root enters d <= 0.3 when x >= -0.3: x = -0.6 + 0.03 n - 0.015 -> n = 11
    assert met_at == 10
    assert reward == pytest.approx(1.0 + 0.03, abs=1e-6)
    assert not terminated and not truncated
    assert np.hypot(*(env.goal_position - env.robot_position)) >= 0.305 + 0.4
    _, reward, *_ = env.step((0.0, 0.0))
    assert abs(reward) < 0.02  # distances restart from the new goal: no jump


def test_button_press_timer_blanks_lidar_and_wrong_button_cost() -> None:
    env = _env("mass", "button", 1, agent=(-0.6, 0.0), buttons=[(0, 0), (0, 1), (0, -1), (1, 1)],
               hazards=[], gremlins=[])  # fmt: skip
    env.goal_button, (env.goal_x, env.goal_y) = 0, (0.0, 0.0)
    env._reset_distances()
    lidar = env.obs_slices["buttons_lidar"]
    pressed = None
    for k in range(60):
        obs, reward, _, _, info = env.step((1.0, 0.0))
        if pressed is None and info["goal_met"]:
            pressed = k
            assert reward > 1.0
            env.goal_button, (env.goal_x, env.goal_y) = 1, env.buttons[1]  # plant a new goal
            env._reset_distances()
        if pressed is not None and k - pressed <= 9:
            assert obs[lidar].max() == 0.0, k
            assert info["cost_buttons"] == 0.0 or k == pressed
        if pressed is not None and k - pressed == 10:
            assert obs[lidar].max() > 0.0
            assert info["cost_buttons"] == 0.0  # computed before the tick: still off at t+10
        if pressed is not None and k - pressed == 11:
            assert info["cost_buttons"] == 1.0  # still pushing against button 0, now wrong
    assert pressed is not None


def test_gremlins_circle_their_placement_at_one_radian_per_second() -> None:
    env = _env("point", "button", 1, agent=(-1.1, -1.1), gremlins=[(0.5, 0.5)], hazards=[],
               buttons=[(-1.1, 1.1), (1.1, -1.1), (1.1, 1.1), (-0.5, -0.2)])  # fmt: skip
    radii, angles = [], []
    for _ in range(314):  # 2*pi s at 0.02 s/step
        env.step((0.0, 0.0))
        dx, dy = np.asarray(env.gremlin_xy[0]) - 0.5
        radii.append(math.hypot(dx, dy))
        angles.append(math.atan2(dx, dy))  # clockwise from +y
    assert np.mean(radii[50:]) == pytest.approx(0.349, abs=0.003)
    unwrapped = np.unwrap(angles)
    rate = (unwrapped[-1] - unwrapped[100]) / ((313 - 100) * 0.02)
    assert rate == pytest.approx(1.0, rel=0.01)


# ------------------------------------------------------------------ no tunnelling
def _penetration(env: SafetyGymEnv) -> float:
    worst = 0.0
    others = list(env._pillar_shapes) + (list(env.box_body.shapes) if env.box_body else [])
    for mine in env.body.shapes:
        for other in others:
            if not mine.bb.intersects(other.bb):
                continue
            try:
                points = mine.shapes_collide(other).points
            except AssertionError:  # pymunk asserts when the shapes do not touch
                continue
            worst = min([worst, *(p.distance for p in points)])
    return -worst


FULL_SPEED = [
    ("point", (1.0, 0.0), 0.0, 0.15),
    ("car", (1.0, 1.0), math.pi / 2, 0.175),
    ("mass", (1.0, 0.0), 0.0, 0.1),
]


@pytest.mark.parametrize(("robot", "action", "yaw", "nose"), FULL_SPEED)
def test_no_tunnelling_through_pillar_or_squeezed_box_at_full_speed(robot, action, yaw, nose):
    env = _env(robot, "push", 2, agent=(-1.5, 0.0), agent_yaw=yaw, push_box=(1.5, 1.5),
               goal=(1.5, -1.5), hazards=[], pillars=[(0.0, 0.0)])  # fmt: skip
    closest = np.inf
    for _ in range(150):
        env.step(action)
        closest = min(closest, float(np.linalg.norm(env.robot_position)))
    assert closest >= 0.2 + nose - 0.02
    assert env.robot_position[0] < 0.0
    for offset in (0.0, 0.1):
        env = _env(robot, "push", 2, agent=(-1.5, offset), agent_yaw=yaw, push_box=(-0.9, 0.0),
                   goal=(1.5, -1.5), hazards=[], pillars=[(0.0, 0.0)])  # fmt: skip
        worst = max(_penetration(env) for _ in range(200) if env.step(action))
        assert worst < 0.06, f"{robot} overlaps the box or pillar by {worst:.3f} m"
