"""The training app end to end on the test CMDP: every algorithm through Hydra compose, the run
directory contract, seeded determinism, crash + resume identity, and fail-fast config errors."""

from __future__ import annotations

import csv
import functools
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hydra.errors import ConfigCompositionException, MissingConfigException
from omegaconf import DictConfig, OmegaConf, open_dict

from semdp.algos.base import POLICY_NAME
from semdp.algos.ppo import PPOLag
from semdp.algos.sac import SAC
from semdp.cli.train import run
from semdp.common.logger import COMMON_COLUMNS, TIMING_COLUMNS
from semdp.evaluation.loading import load_trained

ALGOS = ["ppo", "ppo_lag", "sp_ppo_lag", "trpo", "trpo_lag", "cpo", "sac"]


def _rows(path: Path) -> list[dict[str, str]]:
    with (path / "progress.csv").open() as f:
        return list(csv.DictReader(f))


def _without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


@pytest.mark.parametrize("algo", ALGOS)
def test_train_smoke_writes_the_run_directory_contract(
    algo: str, tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    metrics = run(tiny_train(algo), tmp_path)
    rows = _rows(tmp_path)
    assert [int(r["epoch"]) for r in rows] == [1, 2, 3, 4]
    assert list(rows[0])[: len(COMMON_COLUMNS)] == list(COMMON_COLUMNS)
    assert [int(r["env_steps"]) for r in rows] == [200, 400, 600, 800]
    assert rows[1]["eval_return"] != "" and rows[0]["eval_return"] == ""  # eval_every=2
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved == json.loads(json.dumps(metrics))
    assert saved["status"] == "completed" and saved["env_steps"] == 800
    assert saved["eval"]["episodes"] == 3
    assert (tmp_path / "checkpoints" / "last.pt").is_file()
    config = OmegaConf.load(tmp_path / "config.yaml")
    assert config.cost_limit == 25.0 and config.algo_name
    if algo in ("ppo_lag", "sp_ppo_lag", "trpo_lag"):
        assert config.algo.lagrange.cost_limit == 25.0  # top-level limit interpolated
        assert all(r["lagrange_multiplier"] != "" for r in rows if r["ep_cost"] != "")


def test_train_cost_limit_reaches_the_algorithms(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    cfg = tiny_train("cpo", "cost_limit=7.5")
    run(cfg, tmp_path)
    assert {r["cost_threshold"] for r in _rows(tmp_path)} == {"7.5"}


def test_train_sp_ppo_lag_logs_the_current_threshold_every_epoch(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    # Speeding costs ~30 per episode early on: below 64 -> the schedule tightens 64, 32, 25 ...
    cfg = tiny_train("sp_ppo_lag", "algo.thresholds.initial_exponent=6",
                     "algo.thresholds.num_thresholds=1")
    run(cfg, tmp_path)
    thresholds = [float(r["cost_threshold"]) for r in _rows(tmp_path)]
    assert len(thresholds) == 4 and set(thresholds) <= {64.0, 32.0, 25.0}
    assert thresholds == sorted(thresholds, reverse=True)


@pytest.mark.parametrize("algo", ["ppo_lag", "cpo", "sac"])
def test_train_same_seed_gives_identical_progress(
    algo: str, tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    run(tiny_train(algo), tmp_path / "a")
    run(tiny_train(algo), tmp_path / "b")
    run(tiny_train(algo, "seed=1"), tmp_path / "c")
    a, b, c = (_without_timing(_rows(tmp_path / d)) for d in "abc")
    assert a == b
    assert a != c


@pytest.mark.parametrize(
    ("algo", "cls", "env"),
    [("ppo_lag", PPOLag, "speed_limit"), ("sac", SAC, "speed_limit"),
     ("ppo_lag", PPOLag, "point_goal1")],
    ids=["ppo_lag", "sac", "ppo_lag-pymunk"],
)
def test_train_resume_after_crash_matches_uninterrupted_run(
    algo: str,
    cls: type,
    env: str,
    tiny_train: Callable[..., DictConfig],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    crash_in_epoch_3: Callable[[type], Callable[..., Any]],
) -> None:
    tiny_train = functools.partial(tiny_train, algo, f"env={env}")  # type: ignore[assignment]
    cfg = tiny_train("checkpoint_every=1")
    reference = run(cfg, tmp_path / "ref")
    original = crash_in_epoch_3(cls)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run(tiny_train("checkpoint_every=1"), tmp_path / "crashed")
    failed = json.loads((tmp_path / "crashed" / "metrics.json").read_text())
    assert failed["status"] == "failed" and "simulated crash" in failed["error"]
    assert len(_rows(tmp_path / "crashed")) == 2  # partial CSV kept
    monkeypatch.setattr(cls, "train_epoch", original)
    resumed_cfg = tiny_train()
    with open_dict(resumed_cfg):
        resumed_cfg.resume = str(tmp_path / "crashed")
    resumed = run(resumed_cfg, tmp_path / "ignored")
    assert _without_timing(_rows(tmp_path / "crashed")) == _without_timing(
        _rows(tmp_path / "ref"))
    assert resumed["eval"] == reference["eval"]
    assert resumed["status"] == "completed"


def test_resume_auto_starts_skips_continues_and_refuses_another_config(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    crash_in_epoch_3: Callable[[type], Callable[..., Any]],
) -> None:
    # The rerun of a sweep (same hydra.sweep.dir, resume=auto): a finished job is left as it is,
    # a crashed one continues to the uninterrupted run's numbers, another config is refused.
    auto = functools.partial(tiny_train, "ppo_lag", "resume=auto")
    reference = run(tiny_train("ppo_lag"), tmp_path / "ref")
    fresh = run(auto(), tmp_path / "fresh")
    assert fresh["eval"] == reference["eval"]
    assert OmegaConf.load(tmp_path / "fresh" / "config.yaml").resume is None
    original = crash_in_epoch_3(PPOLag)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run(auto(), tmp_path / "crashed")
    # Finished: returned as saved, nothing trains (train_epoch would crash at epoch 2 here).
    before = (tmp_path / "fresh" / "progress.csv").read_text()
    assert run(auto(), tmp_path / "fresh") == json.loads(
        (tmp_path / "fresh" / "metrics.json").read_text())
    assert (tmp_path / "fresh" / "progress.csv").read_text() == before
    monkeypatch.setattr(PPOLag, "train_epoch", original)
    for done in ("fresh", "crashed"):
        with pytest.raises(ValueError, match=r"another configuration: seed \(0 there, 1 now\)"):
            run(auto("seed=1"), tmp_path / done)
    resumed = run(auto(), tmp_path / "crashed")
    assert resumed["status"] == "completed" and resumed["eval"] == reference["eval"]
    assert _without_timing(_rows(tmp_path / "crashed")) == _without_timing(
        _rows(tmp_path / "ref"))


@pytest.mark.parametrize(
    ("override", "key"),
    [("cost_limit=-1", "cost_limit"), ("total_steps=0", "total_steps"),
     ("budget.steps_per_epoch=0", "algo.steps_per_epoch"), ("seed=-3", "seed"),
     ("env.num_envs=0", "env.num_envs"), ("eval_workers=0", "eval_workers")],
)
def test_train_bad_config_fails_fast_naming_the_key(
    override: str, key: str, tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    with pytest.raises(ValueError, match=key.replace(".", r"\.")):
        run(tiny_train("ppo_lag", override), tmp_path)
    assert not (tmp_path / "progress.csv").exists()


def test_train_cli_bad_config_is_one_line_without_traceback(tmp_path: Path) -> None:
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", "semdp.cli.train", "cost_limit=-1", "budget=ci",
         f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0
    assert "semdp-train: cost_limit must be a finite number >= 0, got -1.0" in done.stderr
    assert "Traceback" not in done.stderr


def test_train_unknown_algo_names_the_algo_group(
    compose_train: Callable[..., DictConfig],
) -> None:
    with pytest.raises((MissingConfigException, ConfigCompositionException), match="algo"):
        compose_train("algo=ppo_lagg")


def test_train_resume_of_a_directory_without_checkpoint_fails(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    with pytest.raises(ValueError, match="resume"):
        run(tiny_train("ppo", f"resume={tmp_path}"), tmp_path / "x")


def test_train_env_wrapper_node_is_applied_to_each_sub_env(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    from semdp.cli.train import build_algorithm

    rescale = "{_target_: gymnasium.wrappers.RescaleAction, _partial_: true, " \
              "min_action: -0.5, max_action: 0.5}"
    cfg = tiny_train("ppo", f"env.wrapper={rescale}")
    algo = build_algorithm(cfg)
    assert float(algo.envs.single_action_space.high[0]) == 0.5
    assert float(algo.eval_envs.single_action_space.high[0]) == 0.5
    narrow = "{_target_: gymnasium.wrappers.RescaleAction, _partial_: true, " \
             "min_action: -0.25, max_action: 0.25}"
    cfg = tiny_train("ppo", f"env.wrapper={rescale}", f"env.eval_wrapper={narrow}")
    algo = build_algorithm(cfg)
    assert float(algo.envs.single_action_space.high[0]) == 0.5
    assert float(algo.eval_envs.single_action_space.high[0]) == 0.25
    assert run(tiny_train("sac", f"env.wrapper={rescale}"), tmp_path)["status"] == "completed"


@pytest.mark.parametrize(
    "extra",
    [["algo/lagrange=pid"], ["algo.thresholds.rule=literal"], ["algo/lagrange=sgd"]],
    ids=["pid", "literal", "sgd-eq-2.10"],
)
def test_train_sp_ppo_lag_variants_run_through_the_app(
    extra: list[str], tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    cfg = tiny_train("sp_ppo_lag", *extra)
    assert run(cfg, tmp_path)["status"] == "completed"
    rows = _rows(tmp_path)
    assert all(float(r["lagrange_multiplier"]) >= 0.0 for r in rows)
    assert all(r["cost_threshold"] != "" for r in rows)


def test_semdp_train_does_not_load_the_planner_for_other_envs() -> None:
    """CasADi and the planner load with a SEMDP env only (start-up of every other run)."""
    import subprocess
    import sys

    code = ("import sys, semdp.cli.train; "
            "print('casadi' in sys.modules, 'solvers.planner' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    assert done.stdout.split() == ["False", "False"]


def test_resume_auto_skips_the_finished_runs_of_a_kept_sweep_on_another_machine(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    crash_in_epoch_3: Callable[[type], Callable[..., Any]],
) -> None:
    # A reference folder keeps metrics.json, progress.csv and config.yaml (no checkpoints):
    # copied back as a sweep directory on a new machine, the rerun skips what finished and
    # starts afresh what had not (no checkpoint travelled), to the same numbers.
    import shutil

    from semdp.experiments.archive import archive_sweep

    auto = functools.partial(tiny_train, "ppo_lag", "resume=auto")
    run(auto(), tmp_path / "sweep" / "0_done")
    original = crash_in_epoch_3(PPOLag)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run(auto(), tmp_path / "sweep" / "1_cut")
    archive_sweep(tmp_path / "sweep", tmp_path / "kept")
    shutil.rmtree(tmp_path / "sweep")  # the old machine is gone
    done = json.loads((tmp_path / "kept" / "0_done" / "metrics.json").read_text())
    assert run(auto(), tmp_path / "kept" / "0_done") == done  # crashes if it trained
    monkeypatch.setattr(PPOLag, "train_epoch", original)
    restarted = run(auto(), tmp_path / "kept" / "1_cut")
    assert restarted["status"] == "completed" and restarted["eval"] == done["eval"]
    assert [int(r["epoch"]) for r in _rows(tmp_path / "kept" / "1_cut")] == [1, 2, 3, 4]


@pytest.mark.parametrize("algo", ["ppo_lag", "sac"])
def test_the_policy_file_alone_evaluates_as_the_checkpoint_does(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, algo: str
) -> None:
    """A reference folder keeps ``policy.pt`` without the checkpoint: loading it must give the
    evaluation of the full checkpoint, episode for episode."""
    run_dir = tmp_path / "run"
    run(tiny_train(algo), run_dir)
    assert (run_dir / POLICY_NAME).is_file()
    from_checkpoint, _ = load_trained(run_dir)
    expected = from_checkpoint.evaluate(4, seed=123)
    shutil.rmtree(run_dir / "checkpoints")
    from_policy, _ = load_trained(run_dir)
    assert from_policy.evaluate(4, seed=123) == expected
    assert from_policy.env_steps == from_checkpoint.env_steps > 0
