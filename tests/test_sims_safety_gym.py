"""Safety Gym replica: registration, gymnasium API, observation layout, determinism, bad input."""

from __future__ import annotations

import copy
import pickle
import warnings

import gymnasium
import numpy as np
import pymunk
import pytest
from gymnasium.utils.env_checker import check_env

import sims
from sims.safety_gym import ENV_IDS, SafetyGymEnv, make
from sims.safety_gym.config import level_spec

# Safety-Gymnasium 1.0.0: observation sizes (Point / Car); Mass uses the Point's 12 sensors
OBS_SIZES = {
    ("goal", 0): (28, 40), ("goal", 1): (60, 72), ("goal", 2): (60, 72),
    ("push", 0): (44, 56), ("push", 1): (76, 88), ("push", 2): (76, 88),
    ("button", 0): (44, 56), ("button", 1): (76, 88), ("button", 2): (76, 88),
}  # fmt: skip


def test_registration_every_id_is_registered_on_import() -> None:
    assert sims.safety_gym.ENV_IDS == ENV_IDS
    assert len(ENV_IDS) == 27
    for name in ENV_IDS:
        assert name in gymnasium.registry
        assert gymnasium.registry[name].max_episode_steps == 1000
    assert "sims/SafetyPointPush1-v0" in ENV_IDS and "sims/SafetyMassGoal2-v0" in ENV_IDS


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_check_env_passes(env_id: str) -> None:
    env = gymnasium.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sensors are unbounded, as in Safety-Gymnasium
        check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize(("task", "level"), sorted(OBS_SIZES))
def test_observation_layout_matches_spec_sizes_and_order(task: str, level: int) -> None:
    point, car = OBS_SIZES[(task, level)]
    for robot, size in (("point", point), ("car", car), ("mass", point)):
        env = SafetyGymEnv(robot, task, level)
        obs, _ = env.reset(seed=0)
        assert obs.shape == (size,) and obs.dtype == np.float64
        names = list(env.obs_slices)
        sensors = ["accelerometer", "velocimeter", "gyro", "magnetometer"]
        if robot == "car":
            sensors += ["ballangvel_rear", "ballquat_rear"]
        lidars = [f"{k}_lidar" for k in level_spec(task, level).lidar_order]
        assert names == sensors + lidars
        assert env.obs_slices[names[-1]].stop == size
    # insertion order of Safety-Gymnasium (Safety-Gymnasium 1.0.0)
    expected = {
        "push": ["goal_lidar", "hazards_lidar", "pillars_lidar", "push_box_lidar"],
        "goal": ["goal_lidar", "hazards_lidar", "vases_lidar"],
        "button": ["buttons_lidar", "goal_lidar", "hazards_lidar", "gremlins_lidar"],
    }[task]
    if level == 0:
        expected = [k for k in expected if k in ("goal_lidar", "push_box_lidar", "buttons_lidar")]
    assert [k for k in SafetyGymEnv("point", task, level).obs_slices if "lidar" in k] == expected


def test_sensors_at_rest_show_gravity_and_magnetic_field() -> None:
    env = SafetyGymEnv("point", "goal", 0)
    yaw = 0.7
    obs, _ = env.reset(seed=0, options={"layout": {"agent": (0, 0), "agent_yaw": yaw}})
    sl = env.obs_slices
    np.testing.assert_allclose(obs[sl["accelerometer"]], [0, 0, 9.81])
    np.testing.assert_allclose(obs[sl["velocimeter"]], [0, 0, 0])
    np.testing.assert_allclose(
        obs[sl["magnetometer"]], [-0.5 * np.sin(yaw), -0.5 * np.cos(yaw), 0], atol=1e-12
    )
    car = SafetyGymEnv("car", "goal", 0)
    obs, _ = car.reset(seed=0)
    np.testing.assert_allclose(obs[car.obs_slices["ballquat_rear"]], np.eye(3).ravel())


@pytest.mark.parametrize("env_id", ["sims/SafetyPointPush1-v0", "sims/SafetyCarButton2-v0",
                                    "sims/SafetyMassGoal2-v0"])  # fmt: skip
def test_seed_fixes_200_steps_of_obs_reward_cost(env_id: str) -> None:
    def rollout(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        env = gymnasium.make(env_id)
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        observations, rewards, costs = [obs], [], []
        for _ in range(200):
            obs, reward, _, _, info = env.step(env.action_space.sample())
            observations.append(obs)
            rewards.append(reward)
            costs.append(info["cost"])
        return np.array(observations), np.array(rewards), np.array(costs)

    a, b, c = rollout(3), rollout(3), rollout(4)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[0], c[0])  # another seed, another layout


def test_layout_respects_extents_and_keepouts() -> None:
    for task in ("goal", "push", "button"):
        for level in (1, 2):
            env = SafetyGymEnv("point", task, level)
            spec = env.layout_spec
            for seed in range(5):
                env.reset(seed=seed)
                placed = [("agent", tuple(env.robot_position))]
                placed += [("hazards", tuple(p)) for p in env.hazards]
                placed += [("pillars", tuple(p)) for p in env.pillars]
                placed += [("buttons", tuple(p)) for p in env.buttons]
                placed += [("gremlins", tuple(p)) for p in env.gremlin_home]
                placed += [("vases", tuple(b.position)) for b in env.vase_bodies]
                if env.box_body is not None:
                    placed.append(("push_box", tuple(env.box_position)))
                if task != "button":
                    placed.append(("goal", tuple(env.goal_position)))
                xmin, ymin, xmax, ymax = spec.extents
                for kind, (x, y) in placed:
                    k = spec.objects[kind].keepout
                    assert xmin + k - 1e-9 <= x <= xmax - k + 1e-9
                    assert ymin + k - 1e-9 <= y <= ymax - k + 1e-9
                for i, (ki, pi) in enumerate(placed):
                    for kj, pj in placed[i + 1 :]:
                        need = spec.objects[ki].keepout + spec.objects[kj].keepout
                        assert np.hypot(pi[0] - pj[0], pi[1] - pj[1]) >= need - 1e-9


def test_counts_and_sizes_follow_the_spec_tables() -> None:
    env = SafetyGymEnv("point", "goal", 2)
    env.reset(seed=0)
    by_type = env.obstacles_by_type()
    assert len(by_type["hazards"]) == 10 and len(by_type["vases"]) == 10
    np.testing.assert_allclose(by_type["hazards"][:, 2], 0.2)
    env = SafetyGymEnv("car", "push", 2)
    env.reset(seed=0)
    assert env.obstacles(("hazards", "pillars")).shape == (8, 3)
    np.testing.assert_allclose(env.obstacles_by_type()["hazards"][:, 2], 0.3)
    assert env.box_half == 0.125
    env = SafetyGymEnv("mass", "button", 2)
    env.reset(seed=0)
    assert env.layout_spec.extents == (-1.8, -1.8, 1.8, 1.8)
    assert [len(env.obstacles_by_type()[k]) for k in ("hazards", "gremlins", "buttons")] == [
        8, 6, 4,
    ]  # fmt: skip
    assert env.obstacles().shape == (14, 3)  # default kinds exclude buttons


def test_info_has_indicator_cost_and_named_terms() -> None:
    expected = {
        ("goal", 0): set(),
        ("goal", 1): {"cost_hazards"},
        ("goal", 2): {"cost_hazards", "cost_vases_contact", "cost_vases_velocity"},
        ("push", 1): {"cost_hazards"},
        ("push", 2): {"cost_hazards", "cost_pillars"},
        ("button", 1): {"cost_hazards", "cost_gremlins", "cost_buttons"},
    }
    for (task, level), terms in expected.items():
        env = SafetyGymEnv("point", task, level)
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.zeros(2))
        assert {k for k in info if k.startswith("cost_") and k != "cost_sum"} == terms
        assert info["cost"] in (0.0, 1.0) and info["cost_sum"] == info["cost"]


def test_episode_truncates_at_1000_steps() -> None:
    env = gymnasium.make("sims/SafetyMassGoal0-v0")
    env.reset(seed=0)
    for k in range(1000):
        _, _, terminated, truncated, _ = env.step(np.zeros(2))
        assert not terminated
        assert truncated == (k == 999)


def test_deepcopy_and_pickle_continue_identically_during_contact() -> None:
    env = SafetyGymEnv("point", "push", 1)
    layout = {"agent": (-1.2, 0), "agent_yaw": 0.0, "push_box": (-0.5, 0.0), "goal": (0.9, 0.5),
              "hazards": [], "pillars": []}  # fmt: skip
    env.reset(seed=0, options={"layout": layout})
    for _ in range(30):
        env.step((1.0, 0.1))
    contacts: list = []
    env.body.each_arbiter(contacts.append)
    assert contacts, "the copy must be taken while the robot pushes the box"
    twin = copy.deepcopy(env)
    pickled = pickle.loads(pickle.dumps(env))
    rng = np.random.default_rng(0)
    for _ in range(200):
        action = rng.uniform(-1, 1, 2)
        expected = env.step(action)
        for other in (twin, pickled):
            got = other.step(action)
            np.testing.assert_array_equal(got[0], expected[0])
            assert got[1:4] == expected[1:4]
            assert got[4]["cost"] == expected[4]["cost"]


def test_bad_inputs_raise_clear_errors() -> None:
    env = SafetyGymEnv("point", "goal", 1)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="2 finite numbers"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="valid robots: point, car, mass"):
        SafetyGymEnv("doggo", "goal", 1)
    with pytest.raises(ValueError, match="valid tasks: goal, button, push"):
        make("point", "circle", 1)
    with pytest.raises(ValueError, match="valid levels: 0, 1, 2"):
        SafetyGymEnv("point", "goal", 3)
    with pytest.raises(ValueError, match="valid"):
        env.obstacles(("walls",))
    with pytest.raises(ValueError, match="unknown layout keys"):
        env.reset(options={"layout": {"walls": [(0, 0)]}})
    with pytest.raises(RuntimeError, match="reset"):
        SafetyGymEnv("point", "goal", 1).step(np.zeros(2))


def test_out_of_range_actions_are_clipped_like_safety_gymnasium() -> None:
    def final_state(action):
        env = SafetyGymEnv("car", "goal", 0)
        env.reset(seed=0, options={"layout": {"agent": (0, 0), "goal": (50, 50)}})
        for _ in range(20):
            env.step(action)
        return env.robot_position

    np.testing.assert_array_equal(final_state([5.0, -7.0]), final_state([1.0, -1.0]))
    np.testing.assert_array_equal(final_state([np.inf, 0.5]), final_state([1.0, 0.5]))


def test_goal_level0_is_a_robot_only_obstacle_free_world() -> None:
    for robot in ("point", "car", "mass"):
        env = SafetyGymEnv(robot, "goal", 0)
        env.reset(seed=0)
        assert env.obstacles().shape == (0, 3)
        assert env.box_position is None
        assert list(env.space.shapes) == list(env.body.shapes)
        env.set_goal_position((1.0, -0.5))
        np.testing.assert_array_equal(env.goal_position, [1.0, -0.5])


def test_sizes_override_changes_geometry_and_cost_radius() -> None:
    env = SafetyGymEnv("point", "push", 2, sizes={"hazard_radius": 0.5, "pillar_radius": 0.1,
                                                  "box_half": 0.1})  # fmt: skip
    env.reset(seed=0, options={"layout": {"agent": (0.0, 0.0), "hazards": [(0.45, 0.0)],
                                          "pillars": [(1.0, 1.0)]}})  # fmt: skip
    assert env.step(np.zeros(2))[4]["cost_hazards"] == 1.0  # inside r = 0.5, outside r = 0.3
    np.testing.assert_allclose(env.obstacles(("pillars",)), [[1.0, 1.0, 0.1]])
    assert env.box_mass == pytest.approx(1.28e-4 / 4)
    with pytest.raises(ValueError, match="valid"):
        SafetyGymEnv("point", "push", 1, sizes={"wall": 1.0})
    with pytest.raises(ValueError, match="positive"):
        SafetyGymEnv("point", "push", 1, sizes={"box_half": -1.0})


def _robot_extent(env) -> float:
    """Largest distance of a robot collision-shape bounding-box corner from the root."""
    x, y = env.body.position
    return max(max(abs(s.bb.left - x), abs(s.bb.right - x), abs(s.bb.bottom - y),
                   abs(s.bb.top - y)) for s in env.body.shapes)


@pytest.mark.parametrize(("robot", "extent"), [("point", 0.15), ("car", 0.175), ("mass", 0.1)])
def test_robot_scale_scales_the_collision_shapes_only(robot: str, extent: float) -> None:
    layout = {"layout": {"agent": (0.0, 0.0), "agent_yaw": 0.0}}
    default = SafetyGymEnv(robot, "push", 1)
    default.reset(seed=0, options=layout)
    assert default.robot_scale == 1.0 and _robot_extent(default) == pytest.approx(extent)
    env = SafetyGymEnv(robot, "push", 1, sizes={"robot_scale": 1.3})
    env.reset(seed=0, options=layout)
    assert env.robot_scale == 1.3 and _robot_extent(env) == pytest.approx(1.3 * extent)
    assert (env.body.mass, env.body.moment) == (default.body.mass, default.body.moment)
    for _ in range(20):  # same actuator response in free space
        obs, *_ = env.step((1.0, 0.3))
        ref, *_ = default.step((1.0, 0.3))
    np.testing.assert_array_equal(env.robot_position, default.robot_position)
    np.testing.assert_array_equal(obs[:12], ref[:12])


def test_robot_scale_bad_values_raise_and_make_passes_it_through() -> None:
    for bad in (0.0, -1.3, float("nan"), float("inf"), "big"):
        with pytest.raises(ValueError, match=r"robot_scale.*positive"):
            SafetyGymEnv("point", "push", 1, sizes={"robot_scale": bad})
    with pytest.raises(ValueError, match="robot_scale"):  # listed among the valid keys
        SafetyGymEnv("point", "push", 1, sizes={"robot_radius": 0.13})
    env = gymnasium.make("sims/SafetyPointPush1-v0", sizes={"robot_scale": 1.3},
                         render_mode="rgb_array", render_size=64)
    env.reset(seed=0)
    assert env.unwrapped.robot_scale == 1.3
    radii = [s.radius for s in env.unwrapped.body.shapes if isinstance(s, pymunk.Circle)]
    assert radii == [pytest.approx(0.13)]
    assert env.render().shape == (64, 64, 3)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_random_rollout_stays_finite_and_in_space(env_id: str) -> None:
    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=7)
    env.action_space.seed(7)
    for _ in range(300):
        obs, reward, _, _, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert np.isfinite(reward) and (abs(reward) < 0.1 or info["goal_met"])
        assert info["cost"] in (0.0, 1.0)
