"""Slow learning checks (run with ``-m slow``; figures recorded in the RL notes).

* PPO and SAC solve Pendulum-v1 (final 50-episode mean-action evaluation >= -300).
* On the test CMDP ``semdp/SpeedLimit-v0`` (cost limit 25 per 100-step episode) unconstrained
  PPO speeds on ~90 steps per episode, while PPO-Lag (PID multiplier) and CPO bring the mean
  training episode cost over the last quarter of the run to 25 +- 20%.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from omegaconf import DictConfig

from semdp.cli.train import run

pytestmark = pytest.mark.slow

CMDP = ["env=speed_limit", "budget=laptop", "budget.steps_per_epoch=4000", "eval_every=0",
        "final_eval_episodes=10"]
LIMIT = 25.0


def _late_cost(run_dir: Path, fraction: float = 0.25) -> float:
    with (run_dir / "progress.csv").open() as f:
        costs = [float(r["ep_cost"]) for r in csv.DictReader(f)]
    tail = costs[-max(1, int(len(costs) * fraction)):]
    return sum(tail) / len(tail)


def test_ppo_reaches_minus_300_on_pendulum(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    # Budget: 200k steps, 4 envs x 1024 steps per epoch, gamma 0.9 (RL-Zoo's Pendulum setting).
    cfg = compose_train("algo=ppo", "env=pendulum", "total_steps=200000",
                        "budget.steps_per_epoch=4096", "algo.gamma=0.9", "algo.actor_lr=1e-3",
                        "algo.critic_lr=1e-3", "algo.target_kl=null", "eval_every=0",
                        "final_eval_episodes=50")
    metrics = run(cfg, tmp_path)
    assert metrics["eval"]["return_mean"] >= -300.0


def test_sac_reaches_minus_300_on_pendulum(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    # Budget: 12k steps (2k random), CleanRL defaults otherwise.
    cfg = compose_train("algo=sac", "env=pendulum", "total_steps=12000",
                        "budget.steps_per_epoch=2000", "algo.learning_starts=2000",
                        "eval_every=0", "final_eval_episodes=50")
    metrics = run(cfg, tmp_path)
    assert metrics["eval"]["return_mean"] >= -300.0


def test_unconstrained_ppo_exceeds_the_cost_limit_on_the_test_cmdp(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    run(compose_train("algo=ppo", *CMDP, "total_steps=200000"), tmp_path)
    assert _late_cost(tmp_path) > 1.2 * LIMIT


def test_ppo_lag_pid_brings_the_cost_to_the_limit_on_the_test_cmdp(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    run(compose_train("algo=ppo_lag", "algo/lagrange=pid", *CMDP, "total_steps=400000"),
        tmp_path)
    assert abs(_late_cost(tmp_path) - LIMIT) <= 0.2 * LIMIT


def test_cpo_brings_the_cost_to_the_limit_on_the_test_cmdp(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    run(compose_train("algo=cpo", *CMDP, "total_steps=200000"), tmp_path)
    assert abs(_late_cost(tmp_path) - LIMIT) <= 0.2 * LIMIT


def test_multirun_cli_runs_jobs_in_parallel_and_survives_a_failing_job(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "semdp.cli.train", "-m", "algo=ppo,cpo", "env=speed_limit",
           "budget=ci", "+env.kwargs.speed_limit=1.0,5.0", f"hydra.sweep.dir={sweep}"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    statuses = {
        d.name: json.loads((d / "metrics.json").read_text())["status"]
        for d in sorted(sweep.iterdir()) if d.is_dir()
    }
    assert statuses == {
        "0_ppo_speed_limit_s0": "completed", "1_ppo_speed_limit_s0": "failed",
        "2_cpo_speed_limit_s0": "completed", "3_cpo_speed_limit_s0": "failed",
    }
