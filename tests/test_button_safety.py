"""The safety layer on the Button tasks: wrong buttons as cost regions (not the goal button, from
the LiDAR as from ground truth, remembered while their channel is blank after a press), the
grace period after a press, and moving gremlins (the stated gremlin law against the simulator,
the orbit discs from ground truth and from the LiDAR, planted robots driven into a gremlin's
orbit)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from shielded_env import ShieldedEnv

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.exit_planning import exit_option
from semdp.embedded.perception import (
    GREMLIN_LAW_TOLERANCE,
    GREMLIN_ORBIT,
    ButtonMemory,
    button_frame,
    gremlin_offset,
    perceive_obstacles,
    wrong_buttons,
)
from semdp.embedded.shield import SafetyShield

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


@pytest.mark.parametrize("perception", ["lidar", "gt"])
@pytest.mark.parametrize(("task", "has_button"), [("Button1", True), ("Push1", False),
                                                  ("Goal1", False)])
def test_a_goal_button_is_read_on_button_tasks_only(perception: str, task: str,
                                                    has_button: bool) -> None:
    """The goal LiDAR of a Goal or Push task sees a goal area, no button: no goal-button rows
    (and no work for them at every low-level step); a Button task's goal button is found."""
    env = gym.make(f"sims/SafetyPoint{task}-v0")
    shield = SafetyShield(perception=perception)
    for seed in range(20):  # a layout whose goal is lit on the goal channel
        obs, _ = env.reset(seed=seed)
        base = env.unwrapped
        if obs[base.obs_slices["goal_lidar"]].max() > 0.0:
            break
    else:
        raise AssertionError("no layout with the goal in LiDAR range")
    shield.bind(base)
    rows = shield.goal_button(base, obs).rows
    assert (len(rows) > 0) is has_button, rows


def test_a_wrong_buttons_aliasing_bound_reads_the_goal_buttons_bin_from_the_whole_channel(
) -> None:
    # the goal button (nearer) owns the bin next to a wrong button's, where the wrong button's
    # alias is outshone; the channel less the goal button's bins reads 0 there, which would
    # bound the wrong button's alpha by 0 and put its region on the wrong edge of its bin
    w = 2 * math.pi / 16
    wrong = (1.5 * math.cos(0.7 * w), 1.5 * math.sin(0.7 * w))   # bin 0, alpha 0.7
    goal = (1.0 * math.cos(1.9 * w), 1.0 * math.sin(1.9 * w))    # bin 1, the goal
    env = gym.make("sims/SafetyPointButton1-v0")
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [], "gremlins": [],
              "buttons": [wrong, (-1.5, 1.5), (-1.3, -1.6), goal]}
    obs, _ = env.reset(seed=SEED_GOAL_ELSEWHERE, options={"layout": layout})
    base = env.unwrapped
    assert base.goal_button == 3
    frame = button_frame(base, obs)
    assert frame.readings[1] == 0.0 and frame.whole[1] > 0.6  # the goal's bin removed
    shield = SafetyShield(perception="lidar", kinds=("buttons",))
    shield.bind(base)
    regions = shield.cost_regions(base, obs)
    allowance = regions[:, 2] - (shield._radii["buttons"] + shield.margin)
    gap = np.linalg.norm(regions[:, :2] - np.array(wrong), axis=1) - allowance
    assert gap.min() <= 1e-9
    assert allowance[int(np.argmin(gap))] < 0.5 * 0.196 * 1.5  # tighter than the whole bin


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
def test_gremlins_keep_to_the_stated_law(robot: str, task: str) -> None:
    """The assumption the planner and the filter rely on: every gremlin sits at its home plus
    the common offset o(t), within the stated tolerance, so it never leaves its orbit disc."""
    env = gym.make(f"sims/Safety{robot.capitalize()}{task}-v0").unwrapped
    worst_law, farthest = 0.0, 0.0
    for seed in range(2):
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        home = np.array(env.gremlin_home)
        for _ in range(400):  # 8 s: more than one revolution, the start-up transient included
            env.step(rng.uniform(-1, 1, 2))
            xy = np.array(env.gremlin_xy)
            law = np.linalg.norm(xy - gremlin_offset(env.sim_time) - home, axis=1).max()
            worst_law = max(worst_law, float(law))
            farthest = max(farthest, float(np.linalg.norm(xy - home, axis=1).max()))
    assert worst_law <= GREMLIN_LAW_TOLERANCE
    assert 0.34 < farthest <= GREMLIN_ORBIT  # the disc is nearly tight


def test_gremlin_offset_at_hand_computed_times() -> None:
    # at rest at home at t = 0; long after the transient, 0.35 / sqrt(1 + 0.09^2) from home,
    # atan(0.09) rad behind the target's bearing (the target at t = pi / 2 is 0.35 (1, 0); the
    # targets turn clockwise)
    np.testing.assert_allclose(gremlin_offset(0.0), [0.0, 0.0], atol=1e-12)
    lagged = gremlin_offset(2 * math.pi + math.pi / 2)
    radius = 0.35 / math.sqrt(1 + 0.09**2)
    behind = math.atan(0.09)
    np.testing.assert_allclose(lagged, radius * np.array([math.cos(behind), math.sin(behind)]),
                               atol=1e-9)


@pytest.mark.parametrize("mode", ["gt", "lidar"])
def test_perceived_gremlins_are_their_orbit_discs(mode: str) -> None:
    homes = [(0.9, 0.3), (-0.8, 0.9)]
    env, obs = _button_env("point", SEED_GOAL_ELSEWHERE, gremlins=homes)
    base = env.unwrapped
    for _ in range(60):  # 1.2 s: every gremlin 0.35 m from its home
        obs, *_ = env.step(np.zeros(2))
    moved = np.linalg.norm(np.array(base.gremlin_xy) - homes, axis=1)
    assert np.all(moved > 0.3)
    found = perceive_obstacles(base, obs, mode, kinds=("gremlins",))
    gaps = np.linalg.norm(found[:, None, :2] - np.array(homes)[None], axis=-1).min(axis=0)
    # centred at the homes (the LiDAR's bin-centre bearing: <= 0.196 m per m of range)
    assert np.all(gaps <= (0.01 if mode == "gt" else 0.25))
    np.testing.assert_allclose(found[:, 2], GREMLIN_ORBIT)  # the planner's eps' adds the size


@pytest.mark.parametrize("robot", ROBOTS)
def test_filter_regions_hold_every_gremlin_orbit(robot: str) -> None:
    # the LiDAR filter's regions (bearing-bounded) contain each true swept disc: home, orbit
    # radius plus the gremlin's and the robot's extents
    env, obs = _button_env(robot, SEED_GOAL_ELSEWHERE, gremlins=[(1.0, 0.6), (-0.7, -1.0)])
    base = env.unwrapped
    shield = SafetyShield(perception="lidar")
    shield.bind(base)
    contact = shield._radii["gremlins"]
    for _ in range(4):
        for _ in range(40):
            obs, *_ = env.step(np.zeros(2))
        regions = shield.cost_regions(base, obs)
        for home in np.array(base.gremlin_home):
            reach = np.linalg.norm(regions[:, :2] - home, axis=1) + GREMLIN_ORBIT + contact
            assert (reach <= regions[:, 2] + 1e-9).any()


def _into_orbit(robot: str, shield: SafetyShield | None, home: tuple[float, float],
                steps: int = 400) -> float:
    """Gremlin cost steps of a robot driven at full speed until its centre is on the orbit of
    a gremlin at ``home`` (0.35 m from it), then held there: the law brings the gremlin round
    within one revolution (6.3 s, 315 steps)."""
    env, _ = _button_env(robot, SEED_GOAL_ELSEWHERE, shield, gremlins=[home],
                         agent=(-1.2, home[1]))
    base = env.unwrapped
    cost = 0.0
    for _ in range(steps):
        on_orbit = base.robot_position[0] >= home[0] - 0.35
        action = np.zeros(2) if on_orbit else np.array(FULL[robot])
        _, _, _, _, info = env.step(action)
        cost += info["cost_gremlins"]
    return cost


@pytest.mark.parametrize(("robot", "perception"), [
    ("point", "lidar"), ("point", "gt"), ("car", "lidar"), ("car", "gt"), ("mass", "lidar"),
    ("mass", "gt")])
def test_filter_keeps_a_robot_driven_into_a_gremlin_orbit_out_of_its_way(
        robot: str, perception: str) -> None:
    home = (0.6, 0.0)
    assert _into_orbit(robot, None, home) > 0  # unfiltered, the gremlin comes round and hits it
    shield = SafetyShield(perception=perception)
    assert _into_orbit(robot, shield, home) == 0.0
    assert shield.stats.braked + shield.stats.escaped > 0


# ------------------------------------------------------------------ the exit from a region
def test_outline_distance_at_hand_computed_points() -> None:
    """The Point's outline (disc r = 0.1 and the nose box x in [0.05, 0.15], |y| <= 0.05)."""
    from semdp.embedded.robot_models import robot_model

    outline = robot_model("point").outline
    points = np.array([[0.3, 0.0], [0.0, 0.3], [0.1, 0.0], [0.15, 0.1], [-0.3, 0.0]])
    np.testing.assert_allclose(outline.distance(0.0, 0.0, 0.0, points),
                               [0.15, 0.2, 0.0, 0.05, 0.2], atol=1e-12)
    # turned a quarter left and moved: the nose points along +y
    np.testing.assert_allclose(outline.distance(1.0, 2.0, math.pi / 2, np.array([[1.0, 2.3]])),
                               [0.15], atol=1e-12)


def _mass_pressing_inside_orbits(seed: int, home_y: float, shield: SafetyShield) -> tuple:
    """(wrong-button cost steps, gremlin cost steps, presses) of a Mass started against the goal
    button (0.25 m from button 0, pushed on into it at full speed for 120 steps) between two
    gremlins whose homes are ``home_y`` from the button's axis (their LiDAR orbit discs around
    the robot)."""
    env, _ = _button_env("mass", seed, shield, gremlins=[(0.6, home_y), (0.6, -home_y)],
                         agent=(0.75, 0.0))
    assert env.unwrapped.goal_button == 0
    costs = np.zeros(3)
    for _ in range(120):
        _, _, _, _, info = env.step(np.array(FULL["mass"]))
        costs += (info["cost_buttons"], info["cost_gremlins"], info["goal_met"])
    return tuple(costs)


@pytest.mark.parametrize("seed", [6, 7, 10])
def test_a_mass_inside_orbit_discs_leaves_the_button_it_pressed(seed: int) -> None:
    """The exit from a just-pressed button ranks the button's region before the orbit discs the
    robot is also in. Under the rule that took the smallest gap over all of them, the discs
    (which the robot cannot leave within the grace period) chose the escapes: 1 wrong-button cost
    step in each of these episodes (checked with that rule patched in; 104 with the gremlins
    0.05 m closer), as on a trained MassButton1 run whose escapes alternated on the button it
    had pressed (1.9 cost per training episode in its epoch 5, 0 when that epoch is replayed
    under this rule; outputs/reference/semdp_button1). With the moving-gremlin certificate the
    Mass leaves by a certified plan: no cost either."""
    shield = SafetyShield(perception="lidar", gremlins="orbit")
    buttons, gremlins, presses = _mass_pressing_inside_orbits(seed, 0.65, shield)
    assert presses >= 1 and shield.stats.escaped > 0
    assert buttons == 0.0 and gremlins == 0.0
    buttons, gremlins, presses = _mass_pressing_inside_orbits(seed, 0.65,
                                                              SafetyShield(gremlins="moving"))
    assert presses >= 1 and buttons == 0.0 and gremlins == 0.0


@pytest.mark.parametrize("command", [[-1.0, 0.0], [0.0, 0.0]])
def test_a_point_between_two_buttons_leaves_the_one_it_pressed(command: list[float]) -> None:
    """A Point pressing the goal button (1, 0) with its back, facing a wrong button 0.6 m away
    whose LiDAR region its way out enters by a few centimetres (within the margin, short of the
    button), commanded back into the pressed button or to stand still: no wrong-button cost.
    With entries not allowed up to the margin the robot could leave neither and stayed on the
    pressed button after its grace period: 2-3 cost steps (checked with the earlier rules
    patched in), as a trained PointButton1 run's epoch-8 episode did."""
    env = gym.make("sims/SafetyPointButton1-v0")
    shield = SafetyShield(perception="lidar")
    env = ShieldedEnv(env, shield)
    layout = {"agent": (1.0, -0.18), "agent_yaw": -math.pi / 2,
              "buttons": [(1.0, 0.0), (-1.5, 1.5), (1.3, 1.6), (1.0, -0.6)],
              "gremlins": [], "hazards": []}
    env.reset(seed=SEED_GOAL_AHEAD, options={"layout": layout})
    assert env.unwrapped.goal_button == 0
    cost = presses = 0.0
    for _ in range(80):
        _, _, _, _, info = env.step(np.array(command))
        cost += info["cost_buttons"]
        presses += info["goal_met"]
    assert presses >= 1 and shield.stats.escaped > 0
    assert cost == 0.0

CAR_BETWEEN_BUTTON_AND_HAZARD = {
    "agent": (-0.67559, 0.77313), "agent_yaw": 3.05223,
    "buttons": [(-0.43267, 0.62889), (-0.59541, 1.28633), (-1.05969, 1.16064), (1.2, -1.2)],
    "hazards": [(-1.22655, 0.77069), (1.5, 1.5), (1.5, 0.0), (0.0, -1.5)], "gremlins": []}


@pytest.mark.parametrize("command", [[-0.95, -0.93], [0.0, 0.0], [0.95, 0.93]])
def test_a_car_that_pressed_a_button_with_its_rear_leaves_it(command: list[float]) -> None:
    """A Car touching the goal button with its rear, a hazard 0.55 m ahead (0.3 m beyond the
    button's region), other buttons 0.5 m to its side: the pose of a trained CarButton1 run's
    epoch-51 episode at its press (outputs/reference/semdp_button1/traces). Commanded back into
    the button, to stand still or at the hazard: no wrong-button or hazard cost. Escapes that
    held each option for the whole horizon found every way out either back on the button or
    into the hazard's region, alternated full forward and full reverse in place and touched the
    button after the grace period: 48 cost steps under each command (checked with that rule
    patched in), as the run did."""
    env = ShieldedEnv(gym.make("sims/SafetyCarButton1-v0"), SafetyShield(perception="lidar"))
    env.reset(seed=SEED_GOAL_AHEAD, options={"layout": CAR_BETWEEN_BUTTON_AND_HAZARD})
    assert env.unwrapped.goal_button == 0
    cost = presses = 0.0
    for _ in range(60):
        _, _, _, _, info = env.step(np.array(command))
        cost += info["cost"]
        presses += info["goal_met"]
    assert presses >= 1 and env.shield.stats.escaped > 0
    assert cost == 0.0


def _plans_by_hand(model: object, state: object, options: list[np.ndarray],
                   regions: np.ndarray) -> dict[tuple[int, int], tuple[float, float]]:
    """Each exit plan from ``state`` by the robot model (option ``i`` held for ``hold`` steps,
    then braking, over the exit's steps), disc gaps to ``regions`` rows ``[x, y, R]``:
    ``(i, hold) -> (the smallest gap to row 1: its entry, the largest gap to row 0: how far
    out of it the plan gets)``."""
    from semdp.embedded.exit_planning import EXIT_STEPS

    plans = {}
    for i, action in enumerate(options):
        for hold in range(1, EXIT_STEPS + 1):
            s, points = state, []
            for t in range(EXIT_STEPS):
                a = action if t < hold else model.backup(s)  # type: ignore[attr-defined]
                s = model.step(s, a)  # type: ignore[attr-defined]
                points.append((s.x, s.y))
            gaps = np.linalg.norm(np.array(points)[:, None] - regions[None, :, :2], axis=-1)
            gaps -= regions[:, 2]
            plans[i, hold] = (float(gaps[:, 1].min()), float(gaps[:, 0].max()))
    return plans


@pytest.mark.parametrize("robot", ["point", "car", "mass"])
def test_the_exit_plans_are_the_models_steps(robot: str) -> None:
    """Row ``i * EXIT_STEPS + j - 1`` of the exit's poses holds option ``i`` for ``j`` steps,
    then brakes: each pose equals the model's ``step`` by hand, bit for bit."""
    from semdp.embedded.exit_planning import EXIT_STEPS, _hold_then_brake
    from semdp.embedded.robot_models import RobotState, robot_model

    model = robot_model(robot)
    state = RobotState(0.1, -0.2, 0.3, -0.4, 1.0, 0.5)
    options = [model.backup(state), *model.escapes]
    poses = _hold_then_brake(model, state, options)
    assert poses.shape == (len(options) * EXIT_STEPS, EXIT_STEPS, 3)
    for i, action in enumerate(options):
        for hold in (1, 4, EXIT_STEPS):
            s, by_hand = state, []
            for k in range(EXIT_STEPS):
                s = model.step(s, action if k < hold else model.backup(s))
                by_hand.append((s.x, s.y, s.yaw))
            np.testing.assert_array_equal(poses[i * EXIT_STEPS + hold - 1], np.array(by_hand))


def test_when_every_way_out_enters_a_region_the_exit_enters_least() -> None:
    """A Point sliding west at 0.5 m/s inside an orbit disc (centre 0.3 m east), a hazard's
    region 0.03 m ahead: every option's hold enters it by more than the margin. The exit takes
    an option that enters least (the earlier rule ranked all options by the disc alone and took
    full thrust west, 0.1 m deeper into the hazard's region), computed here by hand with the
    model."""
    from semdp.embedded.robot_models import RobotState, robot_model

    model = robot_model("point")
    state = RobotState(0.0, 0.0, -0.5, 0.0, math.pi, 0.0)
    regions = np.array([[0.3, 0.0, 0.5], [-0.45, 0.0, 0.48]])
    contact, orbit = np.array([True, False]), np.array([True, False])
    outside = np.array([False, True])
    options = [model.backup(state), *model.escapes]
    plans = _plans_by_hand(model, state, options, regions)
    entries = np.array([entry for entry, _ in plans.values()])
    depths = np.array([depth for _, depth in plans.values()])
    shield = SafetyShield(margin=0.05, perception="gt")
    assert (entries < -shield.margin).all()
    choice = exit_option(model, state, options, regions, contact, orbit, outside,
                         shield.margin)
    assert plans[choice][0] == pytest.approx(entries.max(), abs=1e-12)
    assert entries[int(np.argmax(depths))] < entries.max() - 0.09  # what depth chose


def test_a_robot_barely_inside_a_region_does_not_creep_into_another() -> None:
    """A Point at rest 0.02 m inside a hazard's region (not in the hazard: the margin is 0.05
    m), a wrong button's region 0.03 m ahead: thrust would get it out of the hazard's region
    by entering the button's by 0.02 m, within the margin. The exit allows such entries only
    to a robot deeper than the margin in a static region, so it stays out of the button's
    region; allowed always, the robot crept from region to region and, wedged between a
    hazard and a button, slid into the hazard (a trained PointButton1 run's first epoch)."""
    from semdp.embedded.robot_models import RobotState, robot_model

    model = robot_model("point")
    state = RobotState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    regions = np.array([[-0.25, 0.0, 0.27], [0.48, 0.0, 0.45]])
    contact, orbit = np.array([False, True]), np.array([False, False])
    outside = np.array([False, True])
    options = [model.backup(state), *model.escapes]
    plans = _plans_by_hand(model, state, options, regions)
    shield = SafetyShield(margin=0.05, perception="gt")
    creeping = [depth for entry, depth in plans.values() if -shield.margin <= entry < 0.0]
    assert creeping and max(creeping) > max(
        depth for entry, depth in plans.values() if entry >= 0.0)  # what creeping gains
    choice = exit_option(model, state, options, regions, contact, orbit, outside,
                         shield.margin)
    assert plans[choice][0] >= 0.0


# ------------------------------------------------------------------ regressions from the bench
@pytest.mark.parametrize(("robot", "task", "policy", "seed", "config"), [
    ("point", "Button1", "adversarial", 9209, "eval"),
    ("point", "Button2", "wrong_button", 9201, "eval"),
    ("point", "Button1", "goal", 9604, "train"), ("point", "Button1", "goal", 9627, "eval"),
    ("car", "Button2", "goal", 9630, "eval")])
def test_bench_episodes_that_had_cost_have_none(robot: str, task: str, policy: str,
                                                seed: int, config: str) -> None:
    """Episodes of ``semdp-bench safety`` (development seeds) that had cost under earlier rules:
    a gremlin ran over a robot that the filter held still in its way (gremlins under a speed
    bound: 8 cost steps); an escape from a region the robot found itself in drove it into a
    hazard (before escapes kept out of the regions the robot is outside of: 9); and, with
    goal-seeking subgoals, the robot still touched the button it had just pressed when the
    grace period ended (before the exit rule: 4 cost steps, the Point's nose swinging back into
    the button as it turned; the exit rule with the gap measured from a disc of the robot's
    extent rather than its outline: 2 and 3 cost steps, the Point's nose and the Car's
    wheels). Each with the tracking look-ahead it was recorded with (the thesis' 0.2 m; the
    Point's default is 0.4 m since)."""
    from semdp.benchmarks.safety import build_semdp_env, make_policy
    from semdp.evaluation.safety_eval import evaluate_safety

    env = build_semdp_env(robot, task, config, ("robot.lookahead=0.2",))
    stats = evaluate_safety(env, make_policy(policy, env, seed), 1, seed=seed)
    assert stats["episodes"] == 1 and stats["escape_rate"] > 0  # driven to the edge
    assert stats["cost_steps_total"] == 0
