"""DriveCircle-v0 / DriveTrajectory-v0: API, Eqs. A.1/A.2, observations, episodes (App. A.2)."""

from __future__ import annotations

import copy
import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sims  # noqa: F401  (registers the ids)
from sims.driving import DriveCircleEnv, DriveTrajectoryEnv, PurePursuitController, run_episode

ENV_IDS = ["sims/DriveCircle-v0", "sims/DriveTrajectory-v0"]


def _rollout(env: gym.Env, seed: int, steps: int) -> list[tuple]:
    rng = np.random.default_rng(123)
    obs, _ = env.reset(seed=seed)
    out = [(obs.tolist(),)]
    for _ in range(steps):
        action = rng.uniform(-1, 1, size=2).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        out.append((obs.tolist(), reward, terminated, truncated, sorted(info.items())))
        if terminated or truncated:
            obs, _ = env.reset()
            out.append((obs.tolist(),))
    return out


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_passes_check_env_without_warnings(env_id: str) -> None:
    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_seeded_rollouts_are_identical(env_id: str) -> None:
    first = _rollout(gym.make(env_id, desired_speed=3.0), seed=7, steps=150)
    second = _rollout(gym.make(env_id, desired_speed=3.0), seed=7, steps=150)
    other = _rollout(gym.make(env_id, desired_speed=3.0), seed=8, steps=150)
    assert first == second
    assert first != other


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_deepcopy_and_pickle_resume_exactly(env_id: str) -> None:
    env = gym.make(env_id, desired_speed=4.0, render_mode="rgb_array").unwrapped
    env.reset(seed=3)
    for _ in range(20):
        env.step(np.array([0.3, 0.5], dtype=np.float32))
    clones = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    actions = np.random.default_rng(0).uniform(-1, 1, size=(40, 2)).astype(np.float32)

    def play(e: gym.Env) -> list:
        steps = [e.step(a) for a in actions]
        return [(o.tolist(), r, te, tr, sorted(i.items())) for o, r, te, tr, i in steps]

    expected = play(env)
    for clone in clones:
        assert play(clone) == expected
        np.testing.assert_array_equal(clone.render(), env.render())
    assert env.reset(seed=9)[0].tolist() == clones[1].reset(seed=9)[0].tolist()


def test_circle_reward_and_cost_follow_eq_a1_a2() -> None:
    env = DriveCircleEnv(radius=1.0, road_width=0.5, desired_speed=2.0, speed_weight=0.25,
                         heading_weight=1.0)
    env.reset(seed=0)
    # on the circle at angle 0, heading along the tangent (+y), 3 m/s: d = 0, e = 0
    obs, reward, info = env.set_vehicle_state((1.0, 0.0, math.pi / 2, 3.0, 0.0, 0.0))
    assert reward == pytest.approx(-(0.25 * 1.0))
    assert info["cost"] == 0.0
    np.testing.assert_allclose(obs[:6], [0.0, 0.0, 0.0, -3.0, 3.0, 2.0], atol=1e-6)
    # 0.4 m outside (d = -0.4), driving the wrong way (e = pi), 2 m/s
    obs, reward, info = env.set_vehicle_state((1.4, 0.0, -math.pi / 2, 2.0, 0.0, 0.0))
    assert reward == pytest.approx(-(0.4**2 + 0.0 + 1.0))
    assert info["cost"] == pytest.approx(0.4 - 0.25) == info["cost_off_road"]
    assert obs[0] == pytest.approx(-0.4) and abs(obs[1]) == pytest.approx(math.pi)
    # inside (d > 0), 80 degrees off: below the pi/2 threshold of the indicator
    _, reward, info = env.set_vehicle_state((0.8, 0.0, math.pi / 2 + 1.4, 2.0, 0.0, 0.0))
    assert reward == pytest.approx(-(0.2**2))
    assert info["cost"] == 0.0 and info["lateral_distance"] == pytest.approx(0.2)


@pytest.mark.parametrize("env_cls", [DriveCircleEnv, DriveTrajectoryEnv])
def test_env_derivative_observations_match_finite_differences(env_cls: type) -> None:
    env = env_cls(desired_speed=2.0, dt=0.01, episode_length=400)
    controller = PurePursuitController()
    obs, _ = env.reset(seed=1)
    history = [obs]
    for _ in range(300):
        obs, *_ = env.step(controller(env))
        history.append(obs)
    h = np.array(history, dtype=np.float64)[50:]
    d_dot_fd = (h[2:, 0] - h[:-2, 0]) / 0.02
    e_dot_fd = (np.unwrap(h[:, 1])[2:] - np.unwrap(h[:, 1])[:-2]) / 0.02
    np.testing.assert_allclose(h[1:-1, 2], d_dot_fd, atol=0.005)
    np.testing.assert_allclose(h[1:-1, 3], e_dot_fd, atol=0.03)
    assert np.ptp(h[:, 2]) > 0.1 and np.ptp(h[:, 3]) > 0.2  # the check is not vacuous


def test_trajectory_preview_points_lie_on_the_path_ahead() -> None:
    env = DriveTrajectoryEnv(preview_points=10, preview_spacing=0.4)
    obs, _ = env.reset(seed=5)
    controller = PurePursuitController()
    for _ in range(30):
        obs, *_ = env.step(controller(env))
    x, y, psi, *_ = env.vehicle_state
    points = obs[6:].reshape(10, 2).astype(np.float64)
    world_x = x + np.cos(psi) * points[:, 0] - np.sin(psi) * points[:, 1]
    world_y = y + np.sin(psi) * points[:, 0] + np.cos(psi) * points[:, 1]
    path = np.column_stack([env.track.xs, env.track.ys])
    for px, py in zip(world_x, world_y, strict=True):
        assert np.min(np.hypot(path[:, 0] - px, path[:, 1] - py)) < 1e-5
    gaps = np.hypot(np.diff(world_x), np.diff(world_y))
    assert np.all(gaps <= 0.4 + 1e-5) and np.all(gaps > 0.35)  # chords of 0.4 m arcs
    assert points[-1, 0] > points[0, 0] > 0.0  # ahead of the car


def test_random_path_is_seeded_smooth_and_curvature_bounded() -> None:
    env = DriveTrajectoryEnv(max_curvature=0.5, max_heading=0.9)
    env.reset(seed=11)
    a = (list(env.track.xs), list(env.track.ys))
    env.reset(seed=12)
    b = (env.track.xs, env.track.ys)
    env.reset(seed=11)
    assert a == (env.track.xs, env.track.ys) and a != b
    heading = np.array(env.track.headings)
    curvature = np.array(env.track.curvatures)
    assert np.abs(curvature).max() <= 0.5 + 1e-12 and np.abs(heading).max() <= 0.9 + 1e-12
    np.testing.assert_allclose(np.gradient(heading, env.track.spacing)[1:-1], curvature[1:-1],
                               atol=1e-3)
    xs, ys = np.array(env.track.xs), np.array(env.track.ys)
    np.testing.assert_allclose(np.hypot(np.diff(xs), np.diff(ys)), env.track.spacing, rtol=1e-3)
    assert np.all(np.diff(xs) > 0)  # advances along +x: no self-intersection


def test_env_terminates_far_off_road_with_remaining_steps_charged() -> None:
    env = DriveCircleEnv(radius=1.0, road_width=0.5, off_road_margin=0.5, episode_length=100)
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(2, dtype=np.float32))
    env.set_vehicle_state((1.9, 0.0, math.pi / 2, 1.0, 0.0, 0.0))  # d = -0.9 < -0.75
    _, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and not truncated
    d = info["lateral_distance"]
    step_cost = abs(d) - 0.25
    assert info["cost_off_road"] == pytest.approx(step_cost)
    assert info["cost"] == pytest.approx(step_cost * (1 + 89))
    assert info["cost_termination"] == pytest.approx(step_cost * 89)
    assert reward == pytest.approx(info["reward_termination"] * 90 / 89)

    no_stop = DriveCircleEnv(terminate_off_road=False)
    no_stop.reset(seed=0)
    no_stop.set_vehicle_state((1.9, 0.0, math.pi / 2, 1.0, 0.0, 0.0))
    obs, _, terminated, _, _ = no_stop.step(np.zeros(2, dtype=np.float32))
    assert not terminated and no_stop.observation_space.contains(obs)


def test_env_truncates_at_episode_length() -> None:
    env = DriveCircleEnv(episode_length=7, desired_speed=1.0)
    env.reset(seed=0)
    flags = [env.step(np.zeros(2, dtype=np.float32))[2:4] for _ in range(7)]
    assert flags == [(False, False)] * 6 + [(False, True)]


def test_env_rejects_nan_and_clips_out_of_range_actions() -> None:
    env = DriveCircleEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(ValueError, match="two numbers"):
        env.step("go")
    twin = copy.deepcopy(env)
    big = env.step(np.array([5.0, -7.0], dtype=np.float32))
    clipped = twin.step([1.0, -1.0])
    assert big[0].tolist() == clipped[0].tolist() and big[1] == clipped[1]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"desired_speed": 0.0}, "desired_speed"),
        ({"desired_speed": float("nan")}, "desired_speed"),
        ({"road_width": -1.0}, "road_width"),
        ({"dt": 0.0}, "dt"),
        ({"episode_length": 0}, "episode_length"),
        ({"speed_weight": -1.0}, "speed_weight"),
        ({"render_mode": "human"}, "render_mode"),
        ({"radius": 0.5}, "wider than its turns"),
    ],
)
def test_env_rejects_bad_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        DriveCircleEnv(**kwargs)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_renders_road_car_and_trail(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(15):
        env.step(np.array([0.2, 0.6], dtype=np.float32))
    image = env.render()
    assert image.shape == (400, 400, 3) and image.dtype == np.uint8
    colours = {tuple(c) for c in image.reshape(-1, 3)[::7]}
    assert {(220, 50, 50), (70, 70, 76), (86, 140, 72)} <= colours  # car, road, grass
    assert np.any(np.all(image == (90, 170, 255), axis=-1))  # recent path
    assert gym.make(env_id).unwrapped.render() is None


@pytest.mark.parametrize("env_cls", [DriveCircleEnv, DriveTrajectoryEnv])
def test_pure_pursuit_stays_on_the_road_at_2_and_leaves_it_at_6(env_cls: type) -> None:
    controller = PurePursuitController()
    slow = [run_episode(env_cls(desired_speed=2.0), controller, s) for s in range(3)]
    fast = [run_episode(env_cls(desired_speed=6.0), controller, s) for s in range(3)]
    assert all(r["cost"] == 0.0 and r["length"] == 200 for r in slow)
    assert all(r["cost"] > 1.0 for r in fast)
    assert min(r["return"] for r in slow) > max(r["return"] for r in fast)
