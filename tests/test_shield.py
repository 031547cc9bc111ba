"""The low-level safety filter: its robot models against the simulator, and planted runs at a
hazard where the unfiltered robot incurs cost and the filtered one does not."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.robot_models import RobotState, robot_model
from semdp.embedded.shield import SafetyShield, ShieldedEnv

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


def test_a_filter_pickled_before_the_fallback_option_resumes_as_it_was() -> None:
    import pickle

    shield = SafetyShield()
    del shield.__dict__["fallback"]  # what a checkpoint written before the option holds
    restored = pickle.loads(pickle.dumps(shield))
    assert restored.fallback == "escape" and "fallback" not in restored.__dict__


def test_shield_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="margin"):
        SafetyShield(margin=-0.1)
    with pytest.raises(ValueError, match="perception"):
        SafetyShield(perception="sonar")
    with pytest.raises(ValueError, match="kinds"):
        SafetyShield(kinds=("lava",))
    with pytest.raises(ValueError, match="fallback"):
        SafetyShield(fallback="pray")


def _covered_miss(bound: bool, distance: float) -> float:
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
    assert _covered_miss(True, distance) <= 1e-9
    miss = _covered_miss(False, distance)
    assert 0.15 * distance < miss <= 0.2 * distance


def test_bounded_lidar_regions_sit_where_the_lidar_reconstruction_puts_each_lit_bin() -> None:
    # oracle: obstacles_from_lidar with every lit bin kept (the shield inlines its arithmetic)
    from sims.safety_gym.perception import obstacles_from_lidar
    env = gym.make("sims/SafetyPointGoal1-v0")
    layout = {"agent": (0.3, -0.2), "agent_yaw": 0.7, "hazards": [(1.0, 0.4), (-0.8, 1.1)],
              "vases": [(0.2, -1.3)], "goal": (2.0, -2.0)}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    base = env.unwrapped
    shield = SafetyShield(margin=0.05, perception="lidar", kinds=("hazards", "vases"))
    shield.bind(base)
    regions, contact, orbit = shield._regions(base, obs)
    expected, touches = [], []
    chord = 2.0 * math.sin(math.pi / 32)  # a half bin's bearing error per metre of range
    for kind in ("hazards", "vases"):
        found = obstacles_from_lidar(obs[base.obs_slices[f"{kind}_lidar"]], base.robot_position,
                                     base.robot_heading, peaks_only=False)
        ranges = np.linalg.norm(found - np.asarray(base.robot_position), axis=1)
        grow = np.array([shield._radii[kind] + 0.05 + chord * r for r in ranges])
        expected.append(np.column_stack([found, grow]))
        touches += [kind == "vases"] * len(found)
    expected = np.vstack(expected)
    assert len(expected) >= 4  # both kinds lit, several bins each
    np.testing.assert_allclose(regions, expected, rtol=0, atol=1e-12)
    assert contact.tolist() == touches and not orbit.any()
