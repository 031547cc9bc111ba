"""Experiment presets (conf/experiment/, conf/method/) and their evaluation helpers (§3.6)."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.evaluation.transfer_variant import (
    DEFAULT_SIZES,
    ObservationNoise,
    SuccessOnGoal,
    transfer_env_config,
    transfer_wrap,
)
from semdp.experiments.tradeoff import is_semdp_env, with_clearance
from semdp.experiments.transfer import transfer_table
from semdp.paths import CONF_DIR

PRESETS = ("sp_safety_gym", "sp_driving", "semdp_push", "semdp_ablations", "semdp_tradeoff",
           "semdp_goal", "transfer")
BUDGETS = ("ci", "laptop", "paper")


@pytest.fixture(autouse=True)
def _clear_hydra_config():
    """:func:`preset` registers a Hydra config; other tests must not see it."""
    yield
    HydraConfig.instance().cfg = None


def preset(name: str, budget: str, *overrides: str) -> DictConfig:
    """The composed config of ``semdp-train experiment=<name> budget=<budget>`` with the Hydra
    node, registered so that ``${hydra:runtime.choices.budget}`` resolves."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("train", overrides=[f"experiment={name}", f"budget={budget}", *overrides],
                      return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)
    return cfg


def sweep(cfg: DictConfig) -> dict[str, str]:
    return {str(k): str(v) for k, v in cfg.hydra.sweeper.params.items()}


@pytest.mark.parametrize("budget", BUDGETS)
@pytest.mark.parametrize("name", PRESETS)
def test_preset_composes_and_resolves_at_every_budget(name: str, budget: str) -> None:
    cfg = preset(name, budget)
    assert cfg.total_steps > 0 and cfg.algo.steps_per_epoch > 0
    params = sweep(cfg)
    assert params["seed"].startswith("range(0,")
    assert f"/{name}/{budget}/" in str(cfg.hydra.sweep.dir)
    job = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    OmegaConf.to_container(job, resolve=True)  # every interpolation of the job resolves


def test_preset_ci_budget_is_seconds_and_paper_is_the_thesis() -> None:
    ci = preset("sp_safety_gym", "ci")
    assert ci.total_steps <= 4000 and ci.env.num_envs == 2
    paper = preset("sp_safety_gym", "paper")
    assert paper.total_steps == 10_000_000 and paper.cost_limit == 25.0
    params = sweep(paper)
    assert params["seed"] == "range(0,5)"
    assert set(params["env"].split(",")) == {
        f"point_{task}{level}" for task in ("goal", "button", "push") for level in (1, 2)
    }
    assert set(params["algo"].split(",")) == {"ppo_lag", "sp_ppo_lag"}


def test_sp_driving_sweeps_desired_speeds_and_names_envs_by_speed() -> None:
    paper = preset("sp_driving", "paper", "env.kwargs.desired_speed=5.0", "env=drive_trajectory")
    assert sweep(paper)["env.kwargs.desired_speed"] == "1.0,2.0,3.0,4.0,5.0,6.0"
    assert paper.env.id == "sims/DriveTrajectory-v0"
    assert paper.env_name == "drive_trajectory_v5.0"
    assert sweep(preset("sp_driving", "laptop"))["seed"] == "range(0,2)"


@pytest.mark.parametrize("budget", BUDGETS)
def test_semdp_push_baselines_get_four_times_the_env_steps_of_ours(budget: str) -> None:
    ours = preset("semdp_push", budget, "method=ours")
    cpo = preset("semdp_push", budget, "method=cpo")
    k = ours.env.wrapper.k
    assert cpo.total_steps >= 4 * k * ours.total_steps
    assert ours.cost_limit == cpo.cost_limit == 0.0
    if budget == "paper":
        assert k * ours.total_steps == 10_000_000 and cpo.total_steps == 40_000_000
        assert sweep(ours)["seed"] == "range(0,4)"


@pytest.mark.parametrize(
    ("method", "label", "target", "semdp"),
    [("ours", "Ours", "SAC", True), ("ours_gt", "Ours w/ gt", "SAC", True),
     ("ours_wo_lag", "Ours w/o Lag", "SAC", True), ("ppo_lag_sac", "PPO Lag + SAC", "PPOLag", True),
     ("sac_ppo_lag", "SAC + PPO Lag", "SAC", True), ("cpo", "CPO", "CPO", False),
     ("ppo_lag", "PPO Lag", "PPOLag", False), ("trpo_lag", "TRPO Lag", "TRPOLag", False)],
)
def test_semdp_method_picks_label_algorithm_and_env(
    method: str, label: str, target: str, semdp: bool
) -> None:
    cfg = preset("semdp_ablations", "paper", f"method={method}", "robot=car")
    assert cfg.label == cfg.algo_name == label
    assert cfg.algo._target_.rsplit(".", 1)[-1] == target
    assert cfg.env.id == "sims/SafetyCarPush1-v0" and cfg.env_name == "CarPush1"
    assert (cfg.env.get("wrapper") is not None) == semdp
    if method == "ours_gt":
        assert cfg.env.wrapper.perception == "gt"
    if method == "ours_wo_lag":
        assert cfg.env.eval_wrapper.planner == cfg.env.wrapper.planner
        assert cfg.env.eval_wrapper.planner.backend.adaptive is False
    if method == "ours":
        assert cfg.env.eval_wrapper.planner.backend.adaptive is True
        assert cfg.env.wrapper.planner.backend.adaptive is False
        assert cfg.env.wrapper.planner.rescue_backend == "ipopt"  # the Car's rescue


def test_semdp_goal_and_tradeoff_and_transfer_presets() -> None:
    goal = preset("semdp_goal", "paper", "method=ours", "robot=mass")
    assert goal.env.id == "sims/SafetyMassGoal1-v0" and goal.env_name == "MassGoal1"
    assert sweep(goal)["robot"] == "mass,point,car"
    tradeoff = preset("semdp_tradeoff", "laptop")
    assert tradeoff.post_train._target_ == "semdp.experiments.tradeoff.after_training"
    assert list(tradeoff.post_train.clearances) == [0.1, 0.25, 0.5, 0.75]
    transfer = preset("transfer", "ci")
    assert transfer.post_train._target_ == "semdp.experiments.transfer.after_training"
    assert sweep(transfer)["method"] == "ours,trpo_lag"
    # the preset's variant is the CLI's (`eval`): smaller objects, larger goal and robot
    assert dict(transfer.post_train.sizes) == DEFAULT_SIZES
    assert DEFAULT_SIZES["robot_scale"] == 1.3


def _semdp_env_node() -> dict[str, Any]:
    cfg = preset("semdp_push", "ci", "method=ours")
    node = OmegaConf.to_container(cfg.env, resolve=True)
    assert isinstance(node, dict)
    return node


def test_with_clearance_changes_only_the_evaluation_planner() -> None:
    node = _semdp_env_node()
    out = with_clearance(node, 0.25)
    assert out["eval_wrapper"]["planner"]["problem"]["clearance"] == 0.25
    assert node["eval_wrapper"]["planner"]["problem"]["clearance"] == 0.5  # input not mutated
    assert out["wrapper"] == node["wrapper"]
    assert is_semdp_env(node)
    with pytest.raises(ValueError, match="clearance"):
        with_clearance(node, -0.1)
    baseline = {"id": "sims/SafetyPointPush1-v0", "wrapper": None, "eval_wrapper": None}
    assert not is_semdp_env(baseline)
    with pytest.raises(ValueError, match="semdp_"):
        with_clearance(baseline, 0.5)


def test_observation_noise_is_seeded_and_stays_in_bounds() -> None:
    space = gym.spaces.Box(0.0, 1.0, shape=(400,), dtype=np.float32)

    class Constant(gym.Env):
        observation_space, action_space = space, gym.spaces.Discrete(1)

        def reset(self, *, seed=None, options=None):
            return np.full(400, 0.99, dtype=np.float32), {}

    first = ObservationNoise(Constant(), std=0.05).reset(seed=3)[0]
    again = ObservationNoise(Constant(), std=0.05).reset(seed=3)[0]
    other = ObservationNoise(Constant(), std=0.05).reset(seed=4)[0]
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)
    assert first.min() >= 0.0 and first.max() <= 1.0 and (first == 1.0).any()  # clipped
    assert first.dtype == np.float32 and abs(float(np.median(first)) - 0.99) < 0.02
    assert (ObservationNoise(Constant(), std=0.0).reset(seed=0)[0] == np.float32(0.99)).all()
    with pytest.raises(ValueError, match="std"):
        ObservationNoise(Constant(), std=-1.0)


def test_success_on_goal_ends_the_episode_with_success() -> None:
    class Scripted(gym.Env):
        observation_space = gym.spaces.Box(-1, 1, shape=(1,))
        action_space = gym.spaces.Box(-1, 1, shape=(1,))

        def __init__(self, goal_step: int, horizon: int) -> None:
            self.goal_step, self.horizon, self.t = goal_step, horizon, 0

        def reset(self, *, seed=None, options=None):
            self.t = 0
            return np.zeros(1), {}

        def step(self, action):
            self.t += 1
            info = {"cost": 0.0, "goal_met": self.t == self.goal_step}
            return np.zeros(1), 0.0, False, self.t >= self.horizon, info

    env = SuccessOnGoal(Scripted(goal_step=3, horizon=10))
    env.reset()
    outs = [env.step(0.0) for _ in range(3)]
    assert [o[2] for o in outs] == [False, False, True] and outs[-1][4]["success"] == 1.0
    assert "success" not in outs[0][4]
    env = SuccessOnGoal(Scripted(goal_step=99, horizon=2))
    env.reset()
    env.step(0.0)
    _, _, terminated, truncated, info = env.step(0.0)
    assert (terminated, truncated, info["success"]) == (False, True, 0.0)


def test_transfer_variant_resizes_objects_and_cuts_episodes() -> None:
    node = {"id": "sims/SafetyPointPush1-v0", "num_envs": 1, "kwargs": {}, "wrapper": None,
            "eval_wrapper": None}
    sizes = {"hazard_radius": 0.2, "goal_size": 0.45, "robot_scale": 1.3}
    out = transfer_env_config(node, sizes, noise_std=0.05, episode_steps=60)
    assert out["kwargs"] == {"sizes": sizes, "max_episode_steps": 60} and node["kwargs"] == {}
    env = out["eval_wrapper"](gym.make(out["id"], **out["kwargs"]))
    assert env.unwrapped.goal_size == 0.45 and env.unwrapped.hazard_radius == 0.2
    assert env.unwrapped.robot_scale == 1.3
    env.reset(seed=0)
    steps, done, info = 0, False, {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        steps, done = steps + 1, terminated or truncated
    assert steps == 60 and info["success"] == 0.0  # a robot standing still never scores
    radii = [s.radius for s in env.unwrapped.body.shapes if s.radius > 0.0]
    assert radii == [pytest.approx(0.13)]  # the Point's sphere, 1.3 x 0.1
    with pytest.raises(ValueError, match="Push"):
        transfer_env_config({**node, "id": "sims/SafetyPointGoal1-v0"}, sizes, 0.0, 60)
    with pytest.raises(ValueError, match="episode_steps"):
        transfer_env_config(node, sizes, 0.0, 0)
    assert isinstance(transfer_wrap(gym.make(out["id"]), 0.0, None), SuccessOnGoal)


def test_transfer_table_counts_successes_per_method(tmp_path: Path) -> None:
    def write(name: str, label: str, success: float, ret: float) -> None:
        run = tmp_path / name
        run.mkdir()
        transfer = {"success_rate": success, "return_mean": ret, "cost_mean": 0.0,
                    "layouts": 10, "episodes": 10}
        (run / "metrics.json").write_text(json.dumps(
            {"env": "PointPush1", "label": label, "transfer": transfer}))

    write("a", "Ours", 0.8, 1.0)
    write("b", "Ours", 0.6, 2.0)
    write("c", "TRPO Lag", 0.0, 0.2)
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "metrics.json").write_text(json.dumps({"env": "PointPush1", "algo": "x"}))
    table = transfer_table(tmp_path)
    assert "| PointPush1 | Ours | 2 | 7.0/10 | 1.50 | 0.00 |" in table
    assert "| PointPush1 | TRPO Lag | 1 | 0.0/10 | 0.20 | 0.00 |" in table
    assert "Simulated" in table and "| x |" not in table


def test_reference_reads_the_command_and_summarises_the_sweep(tmp_path: Path) -> None:
    from semdp.experiments.reference import sweep_command, sweep_summary

    (tmp_path / "multirun.yaml").write_text(
        "hydra:\n  overrides:\n    task: [experiment=sp_driving, budget=laptop]\n"
        "    hydra: [hydra.launcher.n_jobs=1, hydra.mode=MULTIRUN, hydra.sweep.dir=/x]\n")
    for name, status, wall in (("0_a", "completed", 60.0), ("1_b", "failed", 30.0)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "metrics.json").write_text(
            json.dumps({"status": status, "wall_time_s": wall}))
    assert sweep_command(tmp_path) == (
        "semdp-train -m experiment=sp_driving budget=laptop hydra.launcher.n_jobs=1")
    summary = sweep_summary(tmp_path)
    assert summary["runs"] == 2 and summary["run_wall_s"] == 90.0
    assert summary["statuses"] == {"completed": 1, "failed": 1}
    with pytest.raises(ValueError, match=r"multirun\.yaml"):
        sweep_command(tmp_path / "0_a")


def test_reference_of_several_sweeps_records_each_command_and_adds_the_counts(
    tmp_path: Path
) -> None:
    from semdp.experiments.reference import write_reference

    sweeps = []
    for seed, wall in ((0, 60.0), (1, 90.0)):
        sweep = tmp_path / f"s{seed}"
        (sweep / "0_run").mkdir(parents=True)
        (sweep / "multirun.yaml").write_text(
            f"hydra:\n  overrides:\n    task: [experiment=sp_driving, seed={seed}]\n"
            "    hydra: [hydra.mode=MULTIRUN]\n")
        (sweep / "0_run" / "metrics.json").write_text(json.dumps(
            {"status": "completed", "wall_time_s": wall, "algo": "ppo_lag", "env": "x",
             "seed": seed, "eval": {"return_mean": 1.0 + seed, "cost_mean": 0.0}}))
        sweeps.append(sweep)
    collected = tmp_path / "collected" / "run"  # runs gathered by hand: no multirun.yaml
    collected.mkdir(parents=True)
    (collected / "metrics.json").write_text(json.dumps(
        {"status": "completed", "wall_time_s": 0.0, "algo": "sac", "env": "y", "seed": 0,
         "eval": {"return_mean": 5.0, "cost_mean": 0.0}}))
    text = write_reference([*sweeps, tmp_path / "collected"], tmp_path / "ref").read_text()
    assert "# collected: run directories collected from several commands" in text
    assert "semdp-train -m experiment=sp_driving seed=0\nsemdp-train -m experiment=sp_driving " \
        "seed=1\n" in text
    assert "- Runs: 3 (3 completed)" in text and "summed training wall time of the runs: 2.5 min" \
        in text and "summed over the 3 sweeps" in text
    assert "| x | reward | 1.50 ± 0.50 |" in text
    assert str(tmp_path / "s0") not in text and "### Results: <sweep dirs>" in text
    assert f"- Machine (where this folder was built): {os.cpu_count()} logical CPUs" in text
    stated = write_reference(sweeps, tmp_path / "ref2", machine="Both lanes at load 3.").read_text()
    line = next(x for x in stated.splitlines() if x.startswith("- Machine"))
    assert platform.python_version() in line and line.endswith(". Both lanes at load 3.")


@pytest.mark.parametrize(
    ("launcher", "plugin", "target"),
    [("local", "hydra_plugins.hydra_joblib_launcher", "JoblibLauncher"),
     ("cluster_slurm", "hydra_plugins.hydra_submitit_launcher", "SlurmLauncher"),
     ("submitit_local", "hydra_plugins.hydra_submitit_launcher", "LocalLauncher"),
     ("cluster_ray", "hydra_plugins.hydra_ray_launcher", "RayLauncher")],
)
def test_launcher_configs_compose_with_a_preset(launcher: str, plugin: str, target: str) -> None:
    import importlib.util

    if importlib.util.find_spec(plugin) is None:
        pytest.skip(f"optional extra not installed ({plugin})")
    cfg = preset("semdp_push", "paper", f"hydra/launcher={launcher}")
    assert cfg.hydra.launcher._target_.endswith(target)
    if launcher == "local":
        assert cfg.hydra.launcher.n_jobs == 2
    if launcher == "cluster_slurm":
        assert (cfg.hydra.launcher.cpus_per_task, cfg.hydra.launcher.timeout_min) == (2, 1440)
    if launcher == "cluster_ray":
        assert cfg.hydra.launcher.ray.remote.num_cpus == 2


def _sweep_with_runs(root: Path, seeds: tuple[int, ...], start: float) -> Path:
    """A sweep directory of completed PPO-Lag runs with planted times and returns."""
    root.mkdir(parents=True)
    (root / "multirun.yaml").write_text(
        "hydra:\n  overrides:\n    task: [experiment=sp_safety_gym]\n    hydra: []\n")
    os.utime(root / "multirun.yaml", (start, start))
    for index, seed in enumerate(seeds):
        run = root / f"{index}_ppo_lag_s{seed}"
        (run / ".hydra").mkdir(parents=True)
        (run / ".hydra" / "overrides.yaml").write_text(f"- seed={seed}\n")
        (run / "checkpoints").mkdir()
        (run / "checkpoints" / "last.pt").write_bytes(b"0" * 1000)
        (run / "config.yaml").write_text(f"cost_limit: 25.0\nseed: {seed}\n")
        (run / "progress.csv").write_text("env_steps,ep_return,ep_cost\n10,1.0,3.0\n20,2.0,1.0\n")
        (run / "metrics.json").write_text(json.dumps(
            {"status": "completed", "wall_time_s": 60.0, "algo": "ppo_lag", "env": "x",
             "seed": seed, "eval": {"return_mean": float(seed), "cost_mean": 0.0}}))
        finish = start + 100.0 * (index + 1)
        os.utime(run / "metrics.json", (finish, finish))
    return root


def test_archived_sweep_keeps_the_light_files_and_the_times_through_a_copy(
    tmp_path: Path
) -> None:
    from semdp.experiments.archive import archive_sweep
    from semdp.experiments.reference import sweep_summary

    sweep = _sweep_with_runs(tmp_path / "sweep", (0, 1), start=1_000_000.0)
    assert archive_sweep(sweep, tmp_path / "kept") == 2
    kept = tmp_path / "kept"
    assert (kept / "0_ppo_lag_s0" / "progress.csv").read_text() == \
        (sweep / "0_ppo_lag_s0" / "progress.csv").read_text()
    assert (kept / "1_ppo_lag_s1" / ".hydra" / "overrides.yaml").is_file()
    assert not (kept / "0_ppo_lag_s0" / "checkpoints").exists()
    # A git checkout sets every file's time to now: the sweep's times must not follow it.
    for path in kept.rglob("*"):
        os.utime(path, (2_000_000.0, 2_000_000.0))
    summary = sweep_summary(kept)
    assert summary["sweep_wall_s"] == pytest.approx(200.0)  # start to the second run's finish
    assert summary["runs"] == 2 and summary["run_wall_s"] == 120.0
    assert summary["finished"] == time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(1_000_200.0))
    assert archive_sweep(kept, kept) == 2  # onto itself: nothing to do
    with pytest.raises(ValueError, match="inside"):
        archive_sweep(sweep, sweep / "0_ppo_lag_s0" / "kept")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not an archive"):
        archive_sweep(sweep, tmp_path / "other")


def test_reference_with_kept_runs_is_rebuilt_and_extended_from_them_alone(
    tmp_path: Path
) -> None:
    import shutil

    from semdp.experiments.reference import write_reference

    first = _sweep_with_runs(tmp_path / "scratch" / "s", (0, 1), start=1_000_000.0)
    out = tmp_path / "ref"
    text = write_reference([first], out, keep_runs=True).read_text()
    assert "| x | reward | 0.50 ± 0.50 |" in text and "`runs/` holds" in text and "`s`" in text
    shutil.rmtree(tmp_path / "scratch")  # the machine is gone; a later seed runs elsewhere
    second = _sweep_with_runs(tmp_path / "later" / "s", (2,), start=1_000_500.0)
    rebuilt = write_reference([out / "runs" / "s", second], out, keep_runs=True).read_text()
    assert "| x | reward | 1.00 ± 0.58 |" in rebuilt and "- Runs: 3 (3 completed)" in rebuilt
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["s", "s_2"]
    assert (out / "runs" / "s_2" / "0_ppo_lag_s2" / "metrics.json").is_file()
    # Built again from one archive only: runs/ holds exactly what the table was built from.
    write_reference([out / "runs" / "s_2"], out, keep_runs=True)
    assert [p.name for p in (out / "runs").iterdir()] == ["s_2"]
