"""Every route to a configuration composes what runs: the robot-specific keys of every preset x
robot x method, the same SEMDP env node from every route, the robot x task env options as the
files they replace, every budget number from conf/budget, and config keys that are constructor
arguments (conf/planner, the robots' followers, every env wrapper)."""

from __future__ import annotations

import importlib
import inspect
import shutil
from pathlib import Path
from typing import Any

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from semdp import env_products
from semdp.cli.train import _config_differences
from semdp.configs import compose_config, group_options
from semdp.paths import CONF_DIR

ROBOTS = ("point", "car", "mass")
SEMDP_METHODS = ("ours", "ours_gt", "ours_wo_lag", "ppo_lag_sac", "sac_ppo_lag")
BASELINES = ("cpo", "ppo_lag", "trpo_lag")
PRESETS = ("semdp_push", "semdp_ablations", "semdp_goal", "semdp_tradeoff", "transfer")
#: The robot facts the tests hold the configs to (conf/robot/<robot>.yaml).
RESCUE = {"point": "ipopt", "car": "ipopt", "mass": "ipopt"}
FOLLOWER = {"point": ("PolicyFollower", "point.pt"), "car": ("PolicyFollower", "car.pt"),
            "mass": ("ProportionalFollower", None)}




def _resolved(node: Any) -> dict[str, Any]:
    out = OmegaConf.to_container(node, resolve=True)
    assert isinstance(out, dict)
    return out


def _target(path: str) -> Any:
    module, _, name = path.rpartition(".")
    return getattr(importlib.import_module(module), name)


def _assert_keys_are_arguments(node: dict[str, Any], where: str) -> None:
    params = inspect.signature(_target(node["_target_"])).parameters
    extra = [k for k in node if not k.startswith("_") and k not in params]
    assert not extra, f"{where}: keys {extra} are not arguments of {node['_target_']}"


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("method", SEMDP_METHODS + BASELINES)
def test_every_preset_robot_method_composes_the_robots_settings(
    preset: str, robot: str, method: str
) -> None:
    cfg = compose_config("train", [f"experiment={preset}", "budget=ci", f"robot={robot}",
                                   f"method={method}"])
    env = _resolved(cfg.env)
    title = robot.capitalize()
    assert env["id"] == f"sims/Safety{title}{cfg.task}-v0"
    assert cfg.env_name == f"{title}{cfg.task}"
    if method in BASELINES:
        assert env["wrapper"] is None and "planner" not in env
        return
    for key in ("wrapper", "eval_wrapper"):
        wrapper = env[key]
        planner, follower = wrapper["planner"], wrapper["follower"]
        assert wrapper["brake_steps"] == 0
        assert wrapper["perception"] == ("gt" if method == "ours_gt" else "lidar")
        if method in ("ppo_lag_sac", "sac_ppo_lag"):
            assert planner["_target_"].endswith("StraightLinePlanner")
            assert planner["rescue_backend"] is None
        else:
            assert planner["_target_"] == "solvers.planner.SafeTrajectoryPlanner"
            assert planner["rescue_backend"] == RESCUE[robot], (preset, robot, method, key)
            adaptive = key == "eval_wrapper" and method != "ours_wo_lag"
            assert planner["backend"]["adaptive"] is adaptive
        kind, weights = FOLLOWER[robot]
        if method == "sac_ppo_lag":
            kind, weights = "PolicyFollower", f"{robot}_ppo_lag.pt"
        assert follower["_target_"].endswith(kind)
        assert follower.get("weights") == weights


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize(("task", "preset"), [("push1", "semdp_push"), ("goal1", "semdp_goal")])
def test_env_route_and_preset_route_compose_the_same_semdp_node(
    robot: str, task: str, preset: str
) -> None:
    # loop=sequential: the presets run one env per job (the main job's default runs several
    # in lockstep, conf/loop/pipelined.yaml); the SEMDP node is otherwise the same
    direct = _resolved(compose_config("train", ["experiment=semdp", "loop=sequential",
                                                f"env=semdp_{robot}_{task}"]).env)
    via_preset = _resolved(compose_config("train", [f"experiment={preset}", "budget=laptop",
                                                    f"robot={robot}", "method=ours"]).env)
    # the preset also fixes the episode length of its budget (1000 steps = the env default)
    assert via_preset.pop("kwargs") == {"max_episode_steps": 1000}
    assert direct.pop("kwargs") == {}
    assert direct == via_preset


def test_car_main_job_route_shows_the_rescue_in_the_job_config() -> None:
    cfg = compose_config("train", ["experiment=semdp_push", "robot=car", "method=ours"])
    assert cfg.robot.rescue_backend == "ipopt"
    assert cfg.env.wrapper.planner.rescue_backend == "ipopt"
    assert cfg.env.eval_wrapper.planner.rescue_backend == "ipopt"


@pytest.mark.parametrize("name", group_options("planner"))
def test_every_planner_key_is_a_constructor_argument(name: str) -> None:
    cfg = compose_config(f"planner/{name}")
    _assert_keys_are_arguments(_resolved(cfg.planner), f"conf/planner/{name}.yaml")


@pytest.mark.parametrize("kind", ["follower", "ppo_lag_follower"])
@pytest.mark.parametrize("robot", ROBOTS)
def test_every_follower_key_is_a_constructor_argument(robot: str, kind: str) -> None:
    cfg = compose_config(f"robot/{robot}")
    _assert_keys_are_arguments(_resolved(cfg.robot[kind]), f"conf/robot/{robot}.yaml {kind}")


@pytest.mark.parametrize("name", group_options("env"))
def test_every_env_composes_with_wrapper_keys_that_are_arguments(name: str) -> None:
    cfg: DictConfig = compose_config("train", ["algo=sac", f"env={name}"])
    env = _resolved(cfg.env)
    assert env["id"].endswith("-v0") or env["id"].endswith("-v1")
    for key in ("wrapper", "eval_wrapper"):
        if env.get(key):
            _assert_keys_are_arguments(env[key], f"conf/env/{name}.yaml {key}")
            for part in ("planner", "follower"):
                if isinstance(env[key].get(part), dict):
                    _assert_keys_are_arguments(env[key][part], f"{name} {key}.{part}")


# ------------------------------------------------------------- robot x task env options
#: The YAML files the registered products replace, as they were written by hand.
HAND_WRITTEN = {
    **{name: f"defaults: [_base, _self_]\nid: sims/Safety{name.split('_')[0].title()}"
             f"{name.split('_')[1].title()}-v0\n"
       for name in env_products.product_names() if not name.startswith("semdp_")},
    **{name: f"defaults:\n  - _semdp\n  - override /robot@_global_.robot: {name.split('_')[1]}\n"
             f"  - _self_\n\ntask: {name.split('_')[2].title()}\n"
       for name in env_products.product_names() if name.startswith("semdp_")},
}


@pytest.fixture(scope="module")
def hand_written_conf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of conf/ with each product also written as a file ``env/hand_<name>.yaml``."""
    conf = tmp_path_factory.mktemp("conf") / "conf"
    shutil.copytree(CONF_DIR, conf)
    for name, text in HAND_WRITTEN.items():
        (conf / "env" / f"hand_{name}.yaml").write_text(text)
    return conf


def _job(conf: Path, overrides: list[str]) -> dict[str, Any]:
    with initialize_config_dir(config_dir=str(conf), version_base="1.3"):
        cfg = compose("train", overrides=overrides, return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)
    job = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    return _resolved(job)


def test_the_products_are_the_thirty_robot_x_task_options() -> None:
    names = env_products.product_names()
    assert len(names) == len(set(names)) == 18 + 12
    assert set(names) <= set(group_options("env"))
    # a file of the same name would be matched against the node as a schema (a Hydra error)
    assert not [n for n in names if (CONF_DIR / "env" / f"{n}.yaml").exists()]


@pytest.mark.parametrize("name", env_products.product_names())
@pytest.mark.parametrize("algo", ["ppo_lag", "sac"])
def test_product_composes_what_its_hand_written_file_did(
    name: str, algo: str, hand_written_conf: Path
) -> None:
    registered = _job(hand_written_conf, [f"algo={algo}", f"env={name}"])
    by_hand = _job(hand_written_conf, [f"algo={algo}", f"env=hand_{name}"])
    assert registered == by_hand
    assert list(registered["env"]) == list(by_hand["env"])  # key order too (the saved config)


def test_product_oracles() -> None:
    button = _resolved(compose_config("train", ["env=car_button2"]).env)
    assert button == {"num_envs": 10, "kwargs": {}, "wrapper": None, "eval_wrapper": None,
                      "add_zero_cost": False, "id": "sims/SafetyCarButton2-v0"}
    semdp = compose_config("train", ["algo=sac", "env=semdp_mass_goal2"])
    assert semdp.robot.name == "mass" and semdp.env.task == "Goal2"
    assert semdp.env.id == "sims/SafetyMassGoal2-v0"
    assert semdp.env.wrapper.follower._target_.endswith("ProportionalFollower")
    # the command line's robot wins over the option's, as it did over the file's
    car = compose_config("train", ["experiment=semdp", "env=semdp_mass_push1", "robot=car"])
    assert car.env.id == "sims/SafetyCarPush1-v0"


@pytest.mark.parametrize(("robot", "env_id", "radius", "steps"),
                         [("point", "sims/SafetyPointGoal0-v0", 0.05, 60_000),
                          ("car", "sims/SafetyCarGoal0-v0", 0.03, 200_000)])
def test_follower_recipes_read_the_robot(robot: str, env_id: str, radius: float,
                                         steps: int) -> None:
    sac = compose_config("train", ["experiment=semdp_follower", f"robot={robot}"])
    assert (sac.env.id, sac.env.wrapper.success_radius, sac.total_steps) == (env_id, radius, steps)
    assert sac.algo.steps_per_epoch == 5000 and sac.algo._target_ == "semdp.algos.SAC"
    low = compose_config("train", ["experiment=semdp_low_ppo_lag", f"robot={robot}"])
    assert low.env.id == env_id.replace("Goal0", "Push1")
    assert low.env.wrapper.success_radius == 0.05 and low.env.wrapper.keep_cost
    assert low.total_steps == 300_000 and low.algo.steps_per_epoch == 10_000
    # a recipe: the budget changes nothing that runs (no periodic evaluation: eval_every 0)
    for recipe, laptop in (("semdp_follower", sac), ("semdp_low_ppo_lag", low)):
        ci = compose_config("train", [f"experiment={recipe}", f"robot={robot}", "budget=ci"])
        assert _config_differences(laptop, ci) == ["eval_episodes"] and ci.eval_every == 0


# ------------------------------------------------------------- one budget mechanism
BUDGETS = ("ci", "laptop", "paper")


def _budget(name: str) -> DictConfig:
    node = OmegaConf.load(CONF_DIR / "budget" / f"{name}.yaml")
    assert isinstance(node, DictConfig)
    return node


@pytest.mark.parametrize("budget", BUDGETS)
def test_every_budget_number_comes_from_the_budget_file(budget: str) -> None:
    numbers = _budget(budget)
    plain = compose_config("train", [f"budget={budget}"])
    assert (plain.total_steps, plain.algo.steps_per_epoch, plain.eval_every, plain.eval_episodes,
            plain.final_eval_episodes) == (numbers.total_steps, numbers.steps_per_epoch,
                                           numbers.eval_every, numbers.eval_episodes,
                                           numbers.final_eval_episodes)
    main = compose_config("train", ["experiment=semdp", f"budget={budget}"])
    assert {k: main[k] for k in ("total_steps", "eval_every", "eval_episodes",
                                 "final_eval_episodes")} | {
        "steps_per_epoch": main.algo.steps_per_epoch} == dict(numbers.semdp)
    gym = compose_config("train", ["experiment=sp_safety_gym", f"budget={budget}"])
    row = numbers.sp_safety_gym
    assert (gym.total_steps, gym.algo.steps_per_epoch, gym.env.num_envs) == (
        row.total_steps, row.steps_per_epoch, row.num_envs)
    driving = compose_config("train", ["experiment=sp_driving", f"budget={budget}"])
    assert (driving.total_steps, driving.algo.steps_per_epoch) == (
        numbers.sp_driving.total_steps, numbers.sp_driving.steps_per_epoch)
    push = numbers.semdp_push
    ours = compose_config("train", ["experiment=semdp_push", f"budget={budget}", "method=ours"])
    assert (ours.total_steps, ours.algo.steps_per_epoch, ours.eval_every, ours.eval_episodes,
            ours.algo.learning_starts, ours.env.kwargs.max_episode_steps) == (
        push.semdp.total_steps, push.semdp.steps_per_epoch, push.semdp.eval_every,
        push.semdp.eval_episodes, push.semdp.learning_starts, push.episode_steps)
    cpo = compose_config("train", ["experiment=semdp_goal", f"budget={budget}", "method=cpo"])
    assert (cpo.total_steps, cpo.algo.steps_per_epoch) == (push.baselines.total_steps,
                                                           push.baselines.steps_per_epoch)
    tradeoff = compose_config("train", ["experiment=semdp_tradeoff", f"budget={budget}"])
    assert tradeoff.tradeoff.episodes == numbers.semdp_tradeoff.episodes
    for cfg in (plain, main, gym, driving, ours, cpo, tradeoff):
        assert "preset" not in cfg


def test_resume_comparison_leaves_the_budget_tables_out() -> None:
    """A run saved with another layout of the tables (the former `preset` tables, a budget
    without sections, a robot with fewer keys) is the same configuration when what runs is the
    same."""
    now = compose_config("train", ["experiment=semdp_push", "budget=ci", "method=cpo"])
    saved = OmegaConf.to_container(now, resolve=True)
    assert isinstance(saved, dict)
    saved["budget"] = {k: saved["budget"][k] for k in ("total_steps", "steps_per_epoch")}
    saved["preset"] = {"name": "semdp_push", "current": {"seeds": 1}}
    del saved["robot"]["follower_success_radius"]  # the robot's table grew a key since
    assert _config_differences(OmegaConf.create(saved), now) == []
    saved["total_steps"] += 1
    assert _config_differences(OmegaConf.create(saved), now) == ["total_steps"]
