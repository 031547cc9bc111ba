"""The low-level safety filter: its robot models against the simulator, and planted runs at a
hazard where the unfiltered robot incurs cost and the filtered one does not."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from shielded_env import ShieldedEnv

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.robot_models import RobotState, robot_model
from semdp.embedded.shield import SafetyShield

ROBOTS = ("point", "car", "mass")


def _state(base) -> RobotState:
    b = base.body
    return RobotState(b.position.x, b.position.y, b.velocity.x, b.velocity.y, b.angle,
                      b.angular_velocity)


@pytest.mark.parametrize("robot", ROBOTS)
def test_robot_model_predicts_the_simulator_one_step_ahead(robot: str) -> None:
    env = gym.make(f"sims/Safety{robot.capitalize()}Goal0-v0").unwrapped
    env.reset(seed=1, options={"layout": {"agent": (0.0, 0.0), "agent_yaw": 0.0,
                                           "goal": (500.0, 500.0)}})
    model, rng = robot_model(robot), np.random.default_rng(0)
    errors = []
    for t in range(200):
        state = _state(env)
        action = rng.uniform(-1, 1, 2) if t % 20 < 15 else model.backup(state)
        predicted = model.step(state, action)
        env.step(action)
        errors.append(math.hypot(predicted.x - env.body.position.x,
                                 predicted.y - env.body.position.y))
    assert max(errors) < 1e-8  # the same actuator law, no contacts in an empty arena


@pytest.mark.parametrize("robot", ROBOTS)
def test_backup_manoeuvre_brings_the_robot_to_rest(robot: str) -> None:
    model = robot_model(robot)
    s = RobotState(0.0, 0.0, 1.2, 0.3, 0.4, 0.0)
    for _ in range(model.horizon):
        s = model.step(s, model.backup(s))
    assert math.hypot(s.vx, s.vy) < 0.15 * math.hypot(1.2, 0.3)


@pytest.mark.parametrize("robot", ROBOTS)
def test_brake_path_is_the_models_braking_steps_bit_for_bit(robot: str) -> None:
    model, rng = robot_model(robot), np.random.default_rng(3)
    for _ in range(20):
        s = RobotState(*rng.uniform(-2, 2, 2), *rng.uniform(-1.5, 1.5, 2),
                       rng.uniform(-math.pi, math.pi), rng.uniform(-3, 3))
        path = model.brake_path(s)
        for i in range(model.horizon):
            s = model.step(s, model.backup(s))
            assert (path[i, 0], path[i, 1]) == (s.x, s.y)


def _drive_at_hazard(robot: str, shield: SafetyShield | None) -> tuple[float, float]:
    """Full speed straight at a hazard planted 1.2 m ahead; (cost steps, closest approach)."""
    env = gym.make(f"sims/Safety{robot.capitalize()}Goal1-v0")
    if shield is not None:
        env = ShieldedEnv(env, shield)
    base = env.unwrapped
    heading = {"point": 0.0, "mass": 0.0, "car": math.pi / 2}[robot]  # Car drives along body -y
    layout = {"agent": (0.0, 0.0), "agent_yaw": heading, "hazards": [(1.2, 0.0)],
              "vases": [(-1.5, 1.5)], "goal": (-1.5, -1.5)}
    env.reset(seed=0, options={"layout": layout})
    full = {"point": [1.0, 0.0], "car": [1.0, 1.0], "mass": [1.0, 0.0]}[robot]
    cost, closest = 0.0, np.inf
    for _ in range(150):
        _, _, _, _, info = env.step(np.array(full))
        cost += info["cost"]
        closest = min(closest, float(np.linalg.norm(base.robot_position - (1.2, 0.0))))
    return cost, closest


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("perception", ["lidar", "gt"])
def test_filter_stops_the_robot_before_a_planted_hazard(robot: str, perception: str) -> None:
    cost, closest = _drive_at_hazard(robot, None)
    assert cost > 0 and closest < 0.1  # unfiltered, the robot drives through the hazard
    shield = SafetyShield(margin=0.05, perception=perception)
    cost, closest = _drive_at_hazard(robot, shield)
    radius = gym.make(f"sims/Safety{robot.capitalize()}Goal1-v0").unwrapped.hazard_radius
    assert cost == 0.0
    assert radius < closest < radius + 0.4  # it stopped close, not far away
    assert shield.stats.braked + shield.stats.escaped > 0


def test_filter_leaves_actions_alone_far_from_obstacles() -> None:
    env = ShieldedEnv(gym.make("sims/SafetyPointGoal1-v0"), SafetyShield())
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [(1.8, 1.8)],
              "vases": [(-1.8, 1.8)], "goal": (-1.5, -1.5)}
    env.reset(seed=0, options={"layout": layout})
    _, _, _, _, info = env.step(np.array([0.02, 0.0]))
    assert info["shield_replaced"] is False
    assert env.shield.stats.checked == 0


@pytest.mark.parametrize("fallback", ["escape", "brake"])
def test_fallback_when_braking_is_not_certified(fallback: str) -> None:
    # 1.5 m/s straight at a hazard whose edge is 0.2 m ahead: neither full thrust nor braking
    # clears it by the model (as after a push by a contact). "escape" picks the best-scoring
    # escape (here full reverse while turning); "brake" keeps braking.
    env = gym.make("sims/SafetyPointGoal1-v0")
    base = env.unwrapped
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [(0.4, 0.0)],
              "vases": [(-1.5, 1.5)], "goal": (-1.5, -1.5)}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    base.body.velocity = (1.5, 0.0)
    shield = SafetyShield(perception="gt", fallback=fallback)
    action = shield.filter(np.array([1.0, 0.0]), base, obs)
    backup = robot_model("point").backup(_state(base))
    if fallback == "brake":
        assert np.array_equal(action, backup)
        assert (shield.stats.braked, shield.stats.escaped) == (1, 0)
    else:
        assert action.tolist() == [-1.0, -1.0] and not np.array_equal(action, backup)
        assert (shield.stats.braked, shield.stats.escaped) == (0, 1)


def test_shield_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="margin"):
        SafetyShield(margin=-0.1)
    with pytest.raises(ValueError, match="perception"):
        SafetyShield(perception="sonar")
    with pytest.raises(ValueError, match="kinds"):
        SafetyShield(kinds=("lava",))
    with pytest.raises(ValueError, match="fallback"):
        SafetyShield(fallback="pray")
    with pytest.raises(ValueError, match="lidar_bearing_bound"):
        SafetyShield(lidar_bearing_bound="sonar")
    with pytest.raises(ValueError, match="lidar_bearing_bound"):  # what runs recorded before
        SafetyShield(lidar_bearing_bound=True)  # the aliasing bound hold: semdp/legacy.py


def _covered_miss(bound: str, distance: float) -> float:
    """Largest distance, over bearings swept through two LiDAR bins, by which the true hazard
    centre lies outside every perceived region's bearing allowance (<= 0: always covered)."""
    env = gym.make("sims/SafetyPointGoal1-v0")
    shield = SafetyShield(margin=0.05, perception="lidar", lidar_bearing_bound=bound)
    worst = -np.inf
    for bearing in np.linspace(0.01, 2 * math.pi / 8 - 0.01, 23):
        hazard = (distance * math.cos(bearing), distance * math.sin(bearing))
        layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [hazard],
                  "vases": [(-2.0, -2.0)], "goal": (2.0, -2.0)}
        obs, _ = env.reset(seed=0, options={"layout": layout})
        shield.bind(env.unwrapped)
        regions = shield.cost_regions(env.unwrapped, obs)
        hazard_radius = env.unwrapped.hazard_radius + 0.05
        allowance = regions[:, 2] - hazard_radius  # what each region adds beyond the margin
        gaps = np.linalg.norm(regions[:, :2] - hazard, axis=1) - allowance
        worst = max(worst, float(gaps.min()))
    return worst


@pytest.mark.parametrize("distance", [0.3, 0.6, 1.2])
def test_lidar_regions_cover_the_true_hazard_at_any_bearing(distance: float) -> None:
    # a LiDAR bin gives the range exactly, the bearing to half a bin: the bounded regions must
    # contain the true centre; the bin-centre reconstruction misses it by up to ~0.196 * d
    assert _covered_miss("aliasing", distance) <= 1e-9
    assert _covered_miss("bin", distance) <= 1e-9
    miss = _covered_miss("none", distance)
    assert 0.15 * distance < miss <= 0.2 * distance


def _hazard_regions(hazards: list[tuple[float, float]], bound: str = "aliasing",
                    agent: tuple[float, float] = (0.0, 0.0), yaw: float = 0.0):
    env = gym.make("sims/SafetyPointGoal1-v0")
    layout = {"agent": agent, "agent_yaw": yaw, "hazards": hazards, "vases": [(-2.9, -2.9)],
              "goal": (2.9, -2.9)}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    shield = SafetyShield(margin=0.05, perception="lidar", kinds=("hazards",),
                          lidar_bearing_bound=bound)
    shield.bind(env.unwrapped)
    allowance = regions = shield.cost_regions(env.unwrapped, obs)
    allowance = regions[:, 2] - (env.unwrapped.hazard_radius + 0.05)
    return regions, allowance, obs[env.unwrapped.obs_slices["hazards_lidar"]]


def test_an_isolated_objects_aliasing_region_is_its_cost_disc_at_the_true_place() -> None:
    # one hazard: its two neighbour bins give alpha exactly, so its region is the hazard's cost
    # disc (+ the float32 tolerances) centred on it; the ghosts in the neighbour bins are either
    # dropped (empty interval) or sit on the bin edge, farther away
    hazard = np.array([1.1 * math.cos(0.5), 1.1 * math.sin(0.5)])
    regions, allowance, _ = _hazard_regions([tuple(hazard)])
    nearest = int(np.argmin(np.linalg.norm(regions[:, :2] - hazard, axis=1)))
    assert np.linalg.norm(regions[nearest, :2] - hazard) < 1e-5
    assert 0.0 < allowance[nearest] < 1e-5
    bin_regions, bin_allowance, _ = _hazard_regions([tuple(hazard)], "bin")
    assert bin_allowance.min() > 0.19 * 1.1 * 0.9  # the whole bin's bound at 1.1 m
    assert len(regions) <= len(bin_regions)


def _seen(hazards: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """Which hazards the filter's law covers: the largest contribution to their own bin
    (the agent at the origin, heading 0; the sensor of sims/safety_gym/lidar.py)."""
    seen = []
    for x, y in hazards:
        d = math.hypot(x, y)
        angle = math.atan2(y, x) % (2 * math.pi)
        i = int(angle / (2 * math.pi / 16)) % 16
        seen.append(d < 3.0 and abs(readings[i] - (3.0 - d) / 3.0) < 1e-6)
    return np.array(seen, dtype=bool)


@pytest.mark.parametrize("seed", range(6))
def test_aliasing_regions_contain_every_object_the_law_covers_in_crowded_layouts(
        seed: int) -> None:
    # planted crowds: 3-5 hazards within 2.5 m, often in neighbouring bins, so that a
    # neighbour's reading is another hazard's and alpha is only bounded, not known; every
    # hazard that is the largest contribution to its own bin must lie in a region's allowance
    rng = np.random.default_rng(seed)
    covered = checked = 0
    for _ in range(40):
        n = int(rng.integers(3, 6))
        ranges = rng.uniform(0.5, 2.5, n)
        bearings = rng.uniform(0.0, 0.9, n) + rng.uniform(0, 2 * math.pi)
        hazards = np.column_stack([ranges * np.cos(bearings), ranges * np.sin(bearings)])
        if np.min(np.linalg.norm(hazards[:, None] - hazards[None], axis=-1)
                  + np.eye(n) * 9) < 0.3:
            continue  # the simulator needs its objects apart
        regions, allowance, readings = _hazard_regions([tuple(h) for h in hazards])
        gaps = np.linalg.norm(hazards[:, None] - regions[None, :, :2], axis=-1) - allowance
        seen = _seen(hazards, readings)
        checked += int(seen.sum())
        assert np.all(gaps.min(axis=1)[seen] <= 1e-9)
        covered += int((gaps.min(axis=1)[seen] <= 1e-9).sum())
    assert checked >= 30


def test_the_aliasing_interval_is_needed_where_a_neighbour_bin_holds_another_object() -> None:
    # two hazards in neighbouring bins: the ratio of readings is not the first hazard's alpha
    # (the neighbour bin holds the second hazard's own reading), and a region at that ratio's
    # bearing would miss it; the interval's region holds it
    w = 2 * math.pi / 16
    first = (1.0 * math.cos(0.3 * w), 1.0 * math.sin(0.3 * w))     # bin 0, alpha 0.3
    second = (1.3 * math.cos(1.5 * w), 1.3 * math.sin(1.5 * w))    # bin 1, nearer its centre
    regions, allowance, readings = _hazard_regions([first, second])
    point_alpha = readings[1] / readings[0]
    assert point_alpha > 0.5  # the naive estimate puts the first hazard in bin 0's far half
    naive = np.array([math.cos(point_alpha * w), math.sin(point_alpha * w)]) * 1.0
    assert np.linalg.norm(naive - first) > 0.1
    gaps = np.linalg.norm(np.array([first, second])[:, None] - regions[None, :, :2],
                          axis=-1) - allowance
    assert np.all(gaps.min(axis=1) <= 1e-9)


def test_bounded_lidar_regions_sit_where_the_lidar_reconstruction_puts_each_lit_bin() -> None:
    # oracle: obstacles_from_lidar with every lit bin kept (the shield inlines its arithmetic)
    from sims.safety_gym.perception import obstacles_from_lidar
    env = gym.make("sims/SafetyPointGoal1-v0")
    layout = {"agent": (0.3, -0.2), "agent_yaw": 0.7, "hazards": [(1.0, 0.4), (-0.8, 1.1)],
              "vases": [(0.2, -1.3)], "goal": (2.0, -2.0)}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    base = env.unwrapped
    shield = SafetyShield(margin=0.05, perception="lidar", kinds=("hazards", "vases"),
                          lidar_bearing_bound="bin")
    shield.bind(base)
    regions, contact, orbit, spread, keepout, own = shield._regions(base, obs)
    expected, touches, keepouts, owns = [], [], [], []
    chord = 2.0 * math.sin(math.pi / 32)  # a half bin's bearing error per metre of range
    for kind in ("hazards", "vases"):
        found = obstacles_from_lidar(obs[base.obs_slices[f"{kind}_lidar"]], base.robot_position,
                                     base.robot_heading, peaks_only=False)
        ranges = np.linalg.norm(found - np.asarray(base.robot_position), axis=1)
        grow = np.array([shield._radii[kind] + 0.05 + chord * r for r in ranges])
        expected.append(np.column_stack([found, grow]))
        touches += [kind == "vases"] * len(found)
        keepouts += [{"hazards": 0.18, "vases": 0.15}[kind]] * len(found)  # the level's spec
        lidar = obs[base.obs_slices[f"{kind}_lidar"]].astype(float)  # an own bin: above both
        owns += [bool(s > lidar[i - 1] and s > lidar[(i + 1) % 16])  # neighbours, else an alias
                 for i, s in enumerate(lidar) if s > 1e-6]
    expected = np.vstack(expected)
    assert len(expected) >= 4  # both kinds lit, several bins each
    np.testing.assert_allclose(regions, expected, rtol=0, atol=1e-12)
    assert contact.tolist() == touches and not orbit.any()
    # the spread: where the object may be around the row's centre, the half bin's chord
    np.testing.assert_allclose(spread, chord * np.linalg.norm(
        expected[:, :2] - np.asarray(base.robot_position), axis=1), rtol=0, atol=1e-12)
    assert keepout.tolist() == keepouts
    assert own.tolist() == owns and 0 < sum(owns) < len(owns)
