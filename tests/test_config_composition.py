"""Every route to a configuration composes what runs: the robot-specific keys of every preset x
robot x method, the same SEMDP env node from every route, and config keys that are constructor
arguments (conf/planner, conf/follower, every env wrapper)."""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path
from typing import Any

import pytest
from omegaconf import DictConfig, OmegaConf

from semdp.configs import compose_config
from semdp.paths import CONF_DIR

ROBOTS = ("point", "car", "mass")
SEMDP_METHODS = ("ours", "ours_gt", "ours_wo_lag", "ppo_lag_sac", "sac_ppo_lag")
BASELINES = ("cpo", "ppo_lag", "trpo_lag")
PRESETS = ("semdp_push", "semdp_ablations", "semdp_goal", "semdp_tradeoff", "transfer")
#: The robot facts the tests hold the configs to (conf/robot/<robot>.yaml).
RESCUE = {"point": "ipopt", "car": "ipopt", "mass": "ipopt"}
FOLLOWER = {"point": ("PolicyFollower", "point.pt"), "car": ("PolicyFollower", "car.pt"),
            "mass": ("ProportionalFollower", None)}


def _options(group: str) -> list[str]:
    return sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml") if p.stem[0] != "_")


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
            assert planner["lm_adaptive"] is adaptive
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


@pytest.mark.parametrize("name", _options("planner"))
def test_every_planner_key_is_a_constructor_argument(name: str) -> None:
    cfg = compose_config(f"planner/{name}")
    _assert_keys_are_arguments(_resolved(cfg.planner), f"conf/planner/{name}.yaml")


@pytest.mark.parametrize("name", _options("follower"))
def test_every_follower_key_is_a_constructor_argument(name: str) -> None:
    cfg = compose_config(f"follower/{name}")
    _assert_keys_are_arguments(_resolved(cfg.follower), f"conf/follower/{name}.yaml")


@pytest.mark.parametrize("name", _options("env"))
def test_every_env_composes_with_wrapper_keys_that_are_arguments(name: str) -> None:
    cfg: DictConfig = compose_config("train", ["algo=sac", f"env={name}"])
    env = _resolved(cfg.env)
    assert Path(CONF_DIR / "env" / f"{name}.yaml").is_file() and env["id"]
    for key in ("wrapper", "eval_wrapper"):
        if env.get(key):
            _assert_keys_are_arguments(env[key], f"conf/env/{name}.yaml {key}")
            for part in ("planner", "follower"):
                if isinstance(env[key].get(part), dict):
                    _assert_keys_are_arguments(env[key][part], f"{name} {key}.{part}")
