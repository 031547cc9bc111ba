"""The safety layer on the Button tasks: wrong buttons as cost regions (not the goal button, from
the LiDAR as from ground truth, remembered while their channel is blank after a press), the
grace period after a press, and moving gremlins (the stated speed bound against the simulator,
planted gremlins driven at and into the robot's path)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.perception import (
    ButtonMemory,
    button_frame,
    gremlin_reach,
    perceive_obstacles,
    wrong_buttons,
)
from semdp.embedded.shield import SafetyShield, ShieldedEnv

ROBOTS = ("point", "car", "mass")
#: Full speed ahead (the Car drives along body -y) and the yaw that points it along +x.
FULL = {"point": [1.0, 0.0], "car": [1.0, 1.0], "mass": [1.0, 0.0]}
YAW = {"point": 0.0, "car": math.pi / 2, "mass": 0.0}
#: Button 0 is 1 m ahead of the robot; seed 0 makes button 3 the goal, seed 2 button 0.
BUTTONS = [(1.0, 0.0), (-1.5, 1.5), (1.3, 1.6), (-1.5, -1.5)]
SEED_GOAL_ELSEWHERE, SEED_GOAL_AHEAD = 0, 2


def _button_env(robot: str, seed: int, shield: SafetyShield | None = None,
                gremlins: list[tuple[float, float]] | None = None,
                agent: tuple[float, float] = (0.0, 0.0)) -> tuple[gym.Env, np.ndarray]:
    env = gym.make(f"sims/Safety{robot.capitalize()}Button1-v0")
    if shield is not None:
        env = ShieldedEnv(env, shield)
    layout = {"agent": agent, "agent_yaw": YAW[robot], "buttons": BUTTONS,
              "gremlins": gremlins or [], "hazards": []}
    obs, _ = env.reset(seed=seed, options={"layout": layout})
    return env, obs


# ------------------------------------------------------------------ buttons: perception
@pytest.mark.parametrize("mode", ["gt", "lidar"])
def test_wrong_buttons_are_obstacles_and_the_goal_button_is_not(mode: str) -> None:
    env, obs = _button_env("point", SEED_GOAL_ELSEWHERE)
    base = env.unwrapped
    assert base.goal_button == 3
    found = perceive_obstacles(base, obs, mode, kinds=("buttons",))
    wrong = np.array(BUTTONS[:3])
    gaps = np.linalg.norm(found[:, None, :2] - wrong[None], axis=-1)
    # every wrong button within LiDAR range is found (bin-centre bearing: <= 0.196 m per m)
    assert np.all(gaps.min(axis=0)[np.linalg.norm(wrong, axis=1) < 3.0] < 0.45)
    # nothing is reconstructed at the goal button
    assert np.linalg.norm(found[:, :2] - BUTTONS[3], axis=1).min() > 0.5
    np.testing.assert_allclose(wrong_buttons(base)[:, :2], wrong)


def test_filter_regions_cover_the_wrong_buttons_and_spare_the_goal_button() -> None:
    env, obs = _button_env("point", SEED_GOAL_ELSEWHERE, agent=(-0.6, -0.6))
    base = env.unwrapped
    shield = SafetyShield(perception="lidar")
    shield.bind(base)
    regions = shield.cost_regions(base, obs)
    contact = shield._radii["buttons"] + shield.margin
    centres = np.array(BUTTONS)
    inside = np.linalg.norm(regions[None, :, :2] - centres[:, None], axis=-1) \
        <= regions[None, :, 2] - contact + 1e-9
    assert inside[:3].any(axis=1).all()  # each wrong button's centre lies in a region's bound
    assert not inside[3].any()  # the goal button's does not


def test_a_blank_button_channel_is_read_from_the_last_lit_frame() -> None:
    # after a press the buttons LiDAR is blank for 10 steps; buttons never move
    env, obs = _button_env("mass", SEED_GOAL_ELSEWHERE)
    base = env.unwrapped
    memory = ButtonMemory()
    lit = button_frame(base, obs, memory)
    assert lit is not None and lit.readings.max() > 0
    base.button_timer = 5  # as during the grace period
    obs, *_ = env.step(np.array([0.5, 0.5]))
    assert obs[base.obs_slices["buttons_lidar"]].max() == 0.0
    remembered = button_frame(base, obs, memory)
    assert remembered is not None
    np.testing.assert_array_equal(remembered.position, [0.0, 0.0])  # the frame's own pose
    assert button_frame(base, obs) is None  # without the memory the buttons are gone
    found = perceive_obstacles(base, obs, "lidar", kinds=("buttons",), memory=memory)
    assert np.linalg.norm(found[:, :2] - BUTTONS[0], axis=1).min() < 0.2
    memory.forget()
    assert button_frame(base, obs, memory) is None
    env.reset(seed=1)
    assert memory.recall(base) is None


# ------------------------------------------------------------------ buttons: planted runs
def _drive_at_button(robot: str, seed: int, shield: SafetyShield | None,
                     steps: int = 150) -> tuple[float, int, int]:
    """Full speed at button 0 (1 m ahead) for ``steps`` steps, pushing on after a press;
    (wrong-button cost steps, presses, the goal button after the last press)."""
    env, _ = _button_env(robot, seed, shield)
    cost, presses = 0.0, 0
    for _ in range(steps):
        _, _, _, _, info = env.step(np.array(FULL[robot]))
        cost += info["cost_buttons"]
        presses += bool(info["goal_met"])
    return cost, presses, env.unwrapped.goal_button


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("perception", ["lidar", "gt"])
def test_filter_keeps_the_robot_off_a_wrong_button(robot: str, perception: str) -> None:
    cost, presses, _ = _drive_at_button(robot, SEED_GOAL_ELSEWHERE, None)
    assert cost > 0 and presses == 0  # unfiltered, the robot runs into the wrong button
    shield = SafetyShield(perception=perception)
    cost, presses, _ = _drive_at_button(robot, SEED_GOAL_ELSEWHERE, shield)
    assert cost == 0.0 and presses == 0
    assert shield.stats.braked + shield.stats.escaped > 0


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("perception", ["lidar", "gt"])
def test_the_goal_button_can_be_pressed_and_then_left_within_the_grace_period(
        robot: str, perception: str) -> None:
    # button 0 is the goal: the robot presses it (twice: the first new goal is button 0 again);
    # the goal moves to another button and the robot, still commanded into button 0, must be
    # off it when the 10-step grace period ends
    cost, presses, goal = _drive_at_button(robot, SEED_GOAL_AHEAD, None)
    assert presses >= 1 and goal != 0 and cost > 0  # unfiltered: it stays on the old goal
    shield = SafetyShield(perception=perception)
    cost, presses, goal = _drive_at_button(robot, SEED_GOAL_AHEAD, shield)
    assert presses == 2 and goal != 0
    assert cost == 0.0


# ------------------------------------------------------------------ gremlins
@pytest.mark.parametrize("task", ["Button1", "Button2"])
@pytest.mark.parametrize("robot", ["point", "car"])
def test_gremlins_keep_to_the_stated_reach(robot: str, task: str) -> None:
    """The assumption the planner and the filter rely on: a gremlin seen at time t is within
    0.35 s + 0.35 exp(-t / 0.09) m of there s seconds later; it is nearly tight."""
    env = gym.make(f"sims/Safety{robot.capitalize()}{task}-v0").unwrapped
    worst, tightest = -np.inf, 0.0
    for seed in range(2):
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        xy, times = [np.array(env.gremlin_xy)], [env.sim_time]
        for _ in range(120):
            env.step(rng.uniform(-1, 1, 2))
            xy.append(np.array(env.gremlin_xy))
            times.append(env.sim_time)
        for i in range(len(times)):
            for j in range(i + 1, min(len(times), i + 50)):
                moved = float(np.linalg.norm(xy[j] - xy[i], axis=1).max())
                bound = gremlin_reach(times[i], times[j] - times[i])
                worst, tightest = max(worst, moved - bound), max(tightest, moved / bound)
    assert worst <= 1e-12
    assert tightest > 0.95


def _pursue(base, speed: float = 0.35, until_s: float = 3.0) -> None:
    """Drive gremlin 0 straight at the robot's current position at ``speed`` (the stated bound)
    until ``until_s``, instead of the replica's circle."""

    def move(h: float) -> None:
        xy, body = base.gremlin_xy[0], base.gremlin_bodies[0]
        offset = np.asarray(base.robot_position) - xy
        distance = float(np.linalg.norm(offset))
        step = speed * h if base.sim_time + h <= until_s and distance > 1e-9 else 0.0
        nx, ny = xy + step * offset / max(distance, 1e-9)
        body.velocity = ((nx - xy[0]) / h, (ny - xy[1]) / h)
        xy[0], xy[1] = float(nx), float(ny)

    base._move_gremlins = move


def _gremlin_cost(robot: str, shield: SafetyShield | None, start: tuple[float, float],
                  action: list[float], steps: int = 200, drive=_pursue,
                  agent: tuple[float, float] = (0.0, 0.0)) -> float:
    """Gremlin cost steps of ``steps`` steps of ``action`` with gremlin 0 planted at ``start``
    and moved by ``drive``."""
    env, _ = _button_env(robot, SEED_GOAL_ELSEWHERE, shield, gremlins=[start], agent=agent)
    drive(env.unwrapped)
    cost = 0.0
    for _ in range(steps):
        _, _, _, _, info = env.step(np.array(action))
        cost += info["cost_gremlins"]
    return cost


@pytest.mark.parametrize(("robot", "perception", "bearing"), [
    ("point", "lidar", 270), ("point", "lidar", 90), ("car", "gt", 270), ("car", "lidar", 90),
    ("mass", "gt", 270), ("mass", "lidar", 90)])
def test_filter_gets_a_standing_robot_away_from_a_gremlin_driven_at_it(
        robot: str, perception: str, bearing: float) -> None:
    start = (0.9 * math.cos(math.radians(bearing)), 0.9 * math.sin(math.radians(bearing)))
    stay = [0.0, 0.0]
    assert _gremlin_cost(robot, None, start, stay) > 0  # it runs the robot over
    shield = SafetyShield(perception=perception)
    assert _gremlin_cost(robot, shield, start, stay) == 0.0
    assert shield.stats.escaped > 0


def _cross(base, start=(0.6, 0.0), velocity=(-0.35, 0.0), travel: float = 1.0) -> None:
    """Drive gremlin 0 from ``start`` at ``velocity`` for ``travel`` metres, then park it."""
    start_arr, velocity_arr = np.asarray(start), np.asarray(velocity)
    speed = float(np.linalg.norm(velocity_arr))

    def move(h: float) -> None:
        t = min(base.sim_time + h, travel / speed)
        nx, ny = start_arr + velocity_arr * t
        xy, body = base.gremlin_xy[0], base.gremlin_bodies[0]
        body.velocity = ((nx - xy[0]) / h, (ny - xy[1]) / h)
        xy[0], xy[1] = float(nx), float(ny)

    base._move_gremlins = move


def test_filter_stops_a_robot_driving_into_the_path_of_an_oncoming_gremlin() -> None:
    # the Point at full speed, a gremlin coming the other way along its path: braking in time
    # for where the gremlin is now is too late for where it will be
    run = {"action": FULL["point"], "steps": 150, "drive": _cross, "agent": (-1.2, 0.0)}
    assert _gremlin_cost("point", None, (0.6, 0.0), **run) > 0
    assert _gremlin_cost("point", SafetyShield(perception="gt"), (0.6, 0.0), **run) == 0.0
