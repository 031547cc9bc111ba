"""The Safety-Embedded MDP wrapper (thesis Alg. 2): reward bookkeeping, planner safety on every
step, tracking-point oracle, perception modes and the ablation planner."""

from __future__ import annotations

import math
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest
from omegaconf import DictConfig, OmegaConf

from semdp.embedded.follower import ProportionalFollower
from semdp.embedded.perception import perceive_obstacles
from semdp.embedded.straight import StraightLinePlanner
from semdp.embedded.tracking import ego_to_world, select_tracking_index, world_to_ego
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.envs import make_env
from solvers.planner import LMSettings, ProblemSettings, SafeTrajectoryPlanner

CLEARANCE = 0.5


class RecordingFollower:
    """A follower that records every low-level action it emits."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.actions: list[np.ndarray] = []

    def act(self, obs, robot_position, robot_heading, target):
        action = self.inner.act(obs, robot_position, robot_heading, target)
        self.actions.append(np.array(action, copy=True))
        return action


def _semdp(env_id: str = "sims/SafetyMassPush1-v0", **kwargs) -> SafetyEmbeddedEnv:
    kwargs.setdefault("planner", SafeTrajectoryPlanner(backend=LMSettings(adaptive=True)))
    kwargs.setdefault("follower", ProportionalFollower(gain=8.0))
    return SafetyEmbeddedEnv(gym.make(env_id), **kwargs)


def test_tracking_index_picks_first_waypoint_beyond_d_min() -> None:
    waypoints = np.array([[0.0, 0.0], [0.1, 0.0], [0.25, 0.0], [0.5, 0.0], [0.6, 0.0]])
    assert select_tracking_index(waypoints, np.zeros(2), 0, 0.2) == 2
    # never moves backwards: from index 3 the robot at the origin still tracks 3
    assert select_tracking_index(waypoints, np.zeros(2), 3, 0.2) == 3
    # near the end nothing is d_min away: the last waypoint is tracked
    assert select_tracking_index(waypoints, np.array([0.55, 0.0]), 3, 0.2) == 4
    # the search starts at the last index, even if that waypoint is behind the robot (B.2.2)
    assert select_tracking_index(waypoints, np.array([0.55, 0.0]), 0, 0.2) == 0
    with pytest.raises(ValueError, match="d_min"):
        select_tracking_index(waypoints, np.zeros(2), 0, -1.0)


def test_tracking_ego_frame_rotation_round_trips() -> None:
    v = np.array([1.0, 0.0])
    assert np.allclose(world_to_ego(v, math.pi / 2), [0.0, -1.0])  # world +x is the robot's right
    assert np.allclose(ego_to_world(np.array([1.0, 0.0]), math.pi / 2), [0.0, 1.0])
    w = np.array([0.3, -0.7])
    assert np.allclose(ego_to_world(world_to_ego(w, 1.1), 1.1), w)


def test_semdp_reward_is_exactly_the_sum_of_inner_rewards() -> None:
    follower = RecordingFollower(ProportionalFollower(gain=8.0))
    env = _semdp(follower=follower, planner=SafeTrajectoryPlanner(backend="lm"))
    replay = gym.make("sims/SafetyMassPush1-v0")
    env.reset(seed=3)
    replay.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(6):
        start = len(follower.actions)
        _, reward, _, _, info = env.step(rng.uniform(-1, 1, size=2))
        inner_reward = inner_cost = 0.0
        for action in follower.actions[start:]:
            _, r, _, _, inner_info = replay.step(action)
            inner_reward += r
            inner_cost += inner_info["cost"]
        assert info["low_level_steps"] == 10 == len(follower.actions) - start
        assert reward == inner_reward
        assert info["cost"] == inner_cost
    assert np.array_equal(env.unwrapped.robot_position, replay.unwrapped.robot_position)


def test_semdp_subgoal_inside_an_obstacle_yields_a_safe_plan() -> None:
    env = _semdp("sims/SafetyMassGoal1-v0", perception="gt")
    layout = {"agent": [(0.0, 0.0)], "hazards": [(1.0, 0.0)], "goal": [(-1.2, 1.2)],
              "vases": [(-1.4, -1.4)]}
    env.reset(seed=0, options={"layout": layout})
    base = env.unwrapped
    hazard = np.array([1.0, 0.0])
    action = 0.5 * world_to_ego(hazard - base.robot_position, base.robot_heading)
    assert np.allclose(env.subgoal_of(action), hazard)
    _, _, _, _, info = env.step(action)
    plan = info["plan"]
    assert info["plan_feasible"] and not info["plan_escape"]
    distances = np.linalg.norm(plan.waypoints - hazard, axis=1)
    assert distances.min() >= CLEARANCE - 1e-9
    assert info["cost"] == 0.0


@pytest.mark.parametrize("perception", ["gt", "lidar"])
def test_semdp_certificate_holds_on_every_step_of_a_rollout(perception: str) -> None:
    """Every waypoint keeps eps' from every perceived obstacle; with ground truth the executed
    robot positions never incur a cost (hazard radius 0.2 < eps' = 0.5)."""
    env = _semdp("sims/SafetyMassGoal1-v0", perception=perception)
    obs, _ = env.reset(seed=1)
    rng = np.random.default_rng(1)
    for _ in range(25):
        perceived = perceive_obstacles(env.unwrapped, obs, perception)
        obs, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, size=2))
        plan = info["plan"]
        if len(perceived) and not plan.escape_mode:
            gaps = np.linalg.norm(plan.waypoints[:, None] - perceived[None, :, :2], axis=-1)
            assert gaps.min() >= CLEARANCE - 1e-9
            assert plan.feasible
        if perception == "gt":
            assert info["cost"] == 0.0
        assert not (terminated or truncated)


def test_semdp_info_carries_timings_and_counts() -> None:
    env = _semdp()
    env.reset(seed=0)
    _, _, _, _, first = env.step(np.zeros(2))
    base = env.unwrapped
    root, heading = base.robot_position.copy(), base.robot_heading
    _, _, _, _, info = env.step(np.array([0.5, -0.5]))
    for key in ("perception_s", "plan_s", "follow_s", "sim_s"):
        assert info[key] > 0.0
        assert env.timing[key] == pytest.approx(first[key] + info[key])
    assert env.high_level_steps == 2 and env.low_level_steps == 20
    # the subgoal is the action times 2 m in the ego frame, from the root at the window start
    assert np.allclose(info["subgoal"], root + ego_to_world(np.array([1.0, -1.0]), heading))
    assert np.allclose(first["subgoal"], first["plan"].waypoints[0])  # a zero action: stay


def test_semdp_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="perception"):
        _semdp(perception="radar")
    with pytest.raises(ValueError, match="k"):
        _semdp(k=0)
    with pytest.raises(ValueError, match="plan"):
        _semdp(planner="teleport")
    with pytest.raises(ValueError, match="act"):
        _semdp(follower="point")
    env = _semdp()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="2 finite numbers"):
        env.step(np.array([np.nan, 0.0]))


def test_semdp_config_overrides_reach_the_instantiated_planner(
    compose_train: Callable[..., DictConfig],
) -> None:
    cfg = compose_train("algo=sac", "env=semdp_mass_push1", "env.planner.problem.clearance=0.7",
                        "env.planner.problem.continuous=true", "planner@env.eval_planner=straight",
                        "env.eval_planner.rescue_backend=null")  # a straight line has no rescue
    env = make_env(cfg.env.id, {}, OmegaConf.to_container(cfg.env.wrapper, resolve=True))
    semdp = env.env
    assert isinstance(semdp, SafetyEmbeddedEnv)
    assert semdp.planner.clearance == 0.7 and semdp.planner.problem.continuous
    assert isinstance(semdp.follower, ProportionalFollower)  # the Mass robot's follower
    eval_env = make_env(cfg.env.id, {}, OmegaConf.to_container(cfg.env.eval_wrapper, resolve=True))
    assert isinstance(eval_env.env.planner, StraightLinePlanner)
    # each env owns its planner (its warm start): two envs from one node do not share it
    other = make_env(cfg.env.id, {}, OmegaConf.to_container(cfg.env.wrapper, resolve=True))
    assert other.env.planner is not semdp.planner



def test_refined_perception_reaches_the_planner_and_leaves_the_filter_its_bound(
    compose_train: Callable[..., DictConfig],
) -> None:
    cfg = compose_train("algo=sac", "env=semdp_point_push1", "env.perception=lidar_refined")
    for node in (cfg.env.wrapper, cfg.env.eval_wrapper):
        semdp = make_env(cfg.env.id, {}, OmegaConf.to_container(node, resolve=True)).env
        assert isinstance(semdp, SafetyEmbeddedEnv)
        assert semdp.perception == "lidar_refined"
        assert semdp.shield is not None and semdp.shield.perception == "lidar"

def test_straight_planner_ignores_obstacles_and_reports_clearance() -> None:
    planner = StraightLinePlanner(ProblemSettings(n_waypoints=5))
    plan = planner.plan([0, 0], [2, 0], [[1.0, 0.0, 0.0]])
    assert np.allclose(plan.waypoints[:, 0], [0, 0.5, 1.0, 1.5, 2.0])
    assert plan.min_clearance == 0.0 and not plan.feasible


def test_perception_gt_and_lidar_find_a_planted_hazard() -> None:
    env = gym.make("sims/SafetyMassGoal1-v0")
    layout = {"agent": [(0.0, 0.0)], "hazards": [(1.0, 0.5)], "goal": [(-1.2, 1.2)],
              "vases": [(-1.4, -1.4)]}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    gt = perceive_obstacles(env.unwrapped, obs, "gt", kinds=("hazards",))
    assert np.allclose(gt, [[1.0, 0.5, 0.0]])
    lidar = perceive_obstacles(env.unwrapped, obs, "lidar", kinds=("hazards",))
    assert len(lidar) >= 1
    # LiDAR reconstruction: bin-centre bearing (16 bins: <= 11.25 deg off) and exact range
    assert np.min(np.linalg.norm(lidar[:, :2] - [1.0, 0.5], axis=1)) < 0.25



@pytest.mark.parametrize("hazard", [(1.0, 0.5), (-0.7, 1.6), (0.3, -2.1)])
def test_refined_lidar_recovers_an_isolated_hazard_exactly(hazard: tuple[float, float]) -> None:
    """``lidar_refined``: the bearing from the neighbouring bins' aliasing puts an isolated
    object at its true position (the bin-centre reconstruction is up to 11.25 deg off)."""
    env = gym.make("sims/SafetyMassGoal1-v0")
    layout = {"agent": [(0.0, 0.0)], "hazards": [hazard], "goal": [(-1.2, 1.2)],
              "vases": [(-1.4, -1.4)]}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    refined = perceive_obstacles(env.unwrapped, obs, "lidar_refined", kinds=("hazards",))
    assert refined.shape == (1, 3)
    np.testing.assert_allclose(refined[0], [*hazard, 0.0], atol=1e-6)
    with pytest.raises(ValueError, match="lidar_refined"):
        perceive_obstacles(env.unwrapped, obs, "lidar2")


def test_the_filter_keeps_its_bin_bound_under_a_refined_planner() -> None:
    from semdp.embedded.shield import SafetyShield

    assert SafetyShield(perception="lidar_refined").perception == "lidar"
    with pytest.raises(ValueError, match="shield perception"):
        SafetyShield(perception="radar")

def test_safety_eval_attributes_violations_to_their_source() -> None:
    from types import SimpleNamespace

    from semdp.evaluation.safety_eval import classify_window

    def plan(waypoints, **flags):
        return SimpleNamespace(waypoints=np.asarray(waypoints, float), feasible=True,
                               fallback=False, escape_mode=False, **flags)

    obstacle = np.array([[1.0, 0.0, 0.3]])
    line = [[0.0, 0.6], [2.0, 0.6]]  # 0.6 m from the centre: safe, segments included
    assert classify_window(plan(line), obstacle, 0.5) == "following"
    assert classify_window(plan([[0.0, 0.4], [1.0, 0.4]]), obstacle, 0.5) == "perception"
    # waypoints 1.2 m apart on both sides: each is 0.6+ m away, the segment passes 0.3 m away
    assert classify_window(plan([[0.4, 0.3], [1.6, 0.3]]), obstacle, 0.5) == "discretisation"
    fallback = plan(line)
    fallback.fallback = True
    assert classify_window(fallback, obstacle, 0.5) == "planner"


BUTTON_LAYOUT = {"agent": [(0.0, 0.0)], "agent_yaw": 0.0, "hazards": [], "gremlins": [],
                 "buttons": [(1.0, 0.0), (-1.5, 1.5), (1.3, 1.6), (-1.5, -1.5)]}


@pytest.mark.parametrize("perception", ["gt", "lidar"])
def test_semdp_keeps_subgoals_at_a_wrong_button_off_it(perception: str) -> None:
    """Button1 with button 0 1 m ahead and button 3 the goal (seed 0): subgoals on button 0
    plan around it and the robot never touches it; the goal button is no obstacle."""
    from semdp.embedded.shield import SafetyShield

    env = _semdp("sims/SafetyMassButton1-v0", perception=perception,
                 shield=SafetyShield(perception=perception))
    obs, _ = env.reset(seed=0, options={"layout": BUTTON_LAYOUT})
    base = env.unwrapped
    assert base.goal_button == 3
    perceived = env.perceive(obs)
    assert np.linalg.norm(perceived[:, :2] - (1.0, 0.0), axis=1).min() < 0.25
    assert np.linalg.norm(perceived[:, :2] - (-1.5, -1.5), axis=1).min() > 0.5
    cost = 0.0
    for _ in range(20):
        target = np.array([1.0, 0.0]) - base.robot_position
        perceived = env.perceive(obs)
        obs, _, _, _, info = env.step(np.clip(world_to_ego(target, base.robot_heading) / 2, -1, 1))
        cost += info["cost"]
        gaps = np.linalg.norm(info["plan"].waypoints[:, None] - perceived[None, :, :2], axis=-1)
        assert info["plan_escape"] or gaps.min() >= CLEARANCE - 1e-9
    assert cost == 0.0


def test_semdp_plans_around_the_gremlins_orbit_discs() -> None:
    from semdp.embedded.perception import GREMLIN_ORBIT

    env = _semdp("sims/SafetyPointButton1-v0", perception="gt", k=10, gremlins="orbit")
    layout = {**BUTTON_LAYOUT, "gremlins": [(0.0, 1.0)]}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    base = env.unwrapped
    for steps in (0, 5):  # at the reset (the gremlin at home) and 1 s in (0.35 m from it)
        for _ in range(steps):
            obs, *_ = env.step(np.zeros(2))
        perceived = env.perceive(obs)
        gremlin = perceived[np.argmin(np.linalg.norm(perceived[:, :2] - (0.0, 1.0), axis=1))]
        np.testing.assert_allclose(gremlin, [0.0, 1.0, GREMLIN_ORBIT], atol=0.005)
    assert np.linalg.norm(np.array(base.gremlin_xy[0]) - (0.0, 1.0)) > 0.3
    # static kinds stay points (the thesis' eps' covers their size)
    others = np.linalg.norm(perceived[:, :2] - (0.0, 1.0), axis=1) > 0.01
    assert np.all(perceived[others, 2] == 0.0)


def test_semdp_plans_around_the_gremlins_where_they_are_when_moving() -> None:
    """``gremlins="moving"``: the planner sees a gremlin where it is, a point (the thesis'
    snapshot; the filter certifies against its motion)."""
    env = _semdp("sims/SafetyPointButton1-v0", perception="gt", k=10, gremlins="moving")
    layout = {**BUTTON_LAYOUT, "gremlins": [(0.0, 1.0)]}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    base = env.unwrapped
    for _ in range(5):  # 1 s in: 0.35 m from its home
        obs, *_ = env.step(np.zeros(2))
    perceived = env.perceive(obs)
    where = np.array(base.gremlin_xy[0])
    gremlin = perceived[np.argmin(np.linalg.norm(perceived[:, :2] - where, axis=1))]
    np.testing.assert_allclose(gremlin, [*where, 0.0], atol=1e-9)
    assert np.linalg.norm(where - (0.0, 1.0)) > 0.3
