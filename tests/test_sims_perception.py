"""Pseudo-LiDAR (Safety-Gymnasium) and the LiDAR-based obstacle reconstruction (thesis §3.6.3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sims.safety_gym import SafetyGymEnv, obstacles_from_lidar
from sims.safety_gym.lidar import fill_pseudo_lidar


def _lidar(points, x=0.0, y=0.0, yaw=0.0) -> np.ndarray:
    out = [0.0] * 16
    fill_pseudo_lidar(out, 0, points, x, y, math.cos(yaw), math.sin(yaw))
    return np.array(out)


def test_lidar_reproduces_the_spec_verified_example() -> None:
    # Safety-Gymnasium 1.0.0: goal at 142.6 deg, d = 1.121 -> bins 5, 6, 7 = 0.415, 0.626, 0.211
    angle = math.radians(142.6)
    lidar = _lidar([(1.121 * math.cos(angle), 1.121 * math.sin(angle))])
    np.testing.assert_allclose(lidar[[5, 6, 7]], [0.415, 0.626, 0.211], atol=1e-3)
    assert np.count_nonzero(lidar) == 3


def test_lidar_is_egocentric_max_combined_and_range_limited() -> None:
    yaw = 1.0
    ahead = (2.0 + math.cos(yaw), 3.0 + math.sin(yaw))  # 1 m along the body +x axis
    lidar = _lidar([ahead, (50.0, 50.0)], x=2.0, y=3.0, yaw=yaw)
    assert lidar[0] == pytest.approx(2.0 / 3.0)  # bin 0 starts at body +x, d = 1
    assert lidar[15] == pytest.approx(2.0 / 3.0)  # aliasing wraps around: (1 - alpha) s, alpha 0
    near_far = _lidar([(1.0, 0.01), (2.0, 0.01)])
    assert near_far[0] == pytest.approx((3.0 - math.hypot(1.0, 0.01)) / 3.0)


def test_car_lidar_bin_12_is_straight_ahead() -> None:
    env = SafetyGymEnv("car", "goal", 0)
    obs, _ = env.reset(seed=0, options={"layout": {"agent": (0, 0), "agent_yaw": 0.3}})
    forward = env.robot_forward_heading
    env.set_goal_position((1.5 * math.cos(forward + 0.01), 1.5 * math.sin(forward + 0.01)))
    obs, *_ = env.step((0.0, 0.0))
    assert int(np.argmax(obs[env.obs_slices["goal_lidar"]])) == 12


@pytest.mark.parametrize("robot", ["point", "car", "mass"])
def test_obstacles_from_lidar_recovers_a_planted_hazard(robot: str) -> None:
    hazard = np.array([0.9, 0.7])
    env = SafetyGymEnv(robot, "goal", 1)
    obs, _ = env.reset(seed=1, options={"layout": {
        "agent": (-0.4, -0.3), "agent_yaw": 0.8, "hazards": [hazard], "vases": [],
        "goal": (-1.2, 1.2)}})  # fmt: skip
    lidar = obs[env.obs_slices["hazards_lidar"]]
    estimate = obstacles_from_lidar(lidar, env.robot_position, env.robot_heading)
    assert estimate.shape == (1, 2)
    distance = np.linalg.norm(hazard - env.robot_position)
    # distance exact, bearing within half a bin (11.25 deg)
    assert np.linalg.norm(estimate[0] - env.robot_position) == pytest.approx(distance)
    assert np.linalg.norm(estimate[0] - hazard) <= 2 * distance * math.sin(math.pi / 32) + 1e-9
    refined = obstacles_from_lidar(lidar, env.robot_position, env.robot_heading,
                                   refine_bearing=True)  # fmt: skip
    np.testing.assert_allclose(refined[0], hazard, atol=1e-9)
    ghosts = obstacles_from_lidar(lidar, env.robot_position, env.robot_heading, peaks_only=False)
    assert len(ghosts) == 3  # the aliasing neighbours come back as farther ghosts
    ground_truth = env.obstacles(("hazards",))
    np.testing.assert_allclose(ground_truth, [[0.9, 0.7, 0.2]])


def test_obstacles_from_lidar_bin_centre_error_bound() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        d, angle = rng.uniform(0.2, 2.9), rng.uniform(0, 2 * math.pi)
        point = np.array([d * math.cos(angle), d * math.sin(angle)])
        estimate = obstacles_from_lidar(_lidar([point]), np.zeros(2), 0.0)
        assert len(estimate) == 1
        assert np.linalg.norm(estimate[0] - point) <= 2 * d * math.sin(math.pi / 32) + 1e-9


def test_obstacles_from_lidar_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="shape"):
        obstacles_from_lidar(np.zeros(10), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="in \\[0, 1\\]"):
        obstacles_from_lidar(np.full(16, 1.5), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="finite"):
        obstacles_from_lidar(np.zeros(16), np.array([np.nan, 0.0]), 0.0)
    assert obstacles_from_lidar(np.zeros(16), np.zeros(2), 0.0).shape == (0, 2)
