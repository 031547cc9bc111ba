"""The SEMDP env configs and presets through the training app (budget=ci, a few steps): the run
directory contract plus the SEMDP artefacts (time split, curves, evaluation GIF, label)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from omegaconf import DictConfig

from semdp.cli.train import run

#: Shrinks a SEMDP preset to seconds: 60 high-level steps, a 2-episode final evaluation.
TINY_SEMDP = [
    "budget=ci", "total_steps=60", "budget.steps_per_epoch=30", "eval_every=2", "eval_episodes=1",
    "final_eval_episodes=2", "++env.kwargs.max_episode_steps=200",
]
TINY_SAC = ["algo.learning_starts=20", "algo.batch_size=16", "algo.hidden_sizes=[16,16]",
            "algo.buffer_size=1000"]


def test_semdp_main_preset_trains_and_writes_artefacts(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    # The main job's loop (conf/loop/pipelined.yaml), with 2 lockstep envs so that 30 divides.
    cfg = compose_train("experiment=semdp", "env=semdp_mass_push1", *TINY_SEMDP, *TINY_SAC,
                        "env.num_envs=2")
    assert cfg.algo.learner == "process" and cfg.env.vector.endswith("LockstepVectorEnv")
    metrics = run(cfg, tmp_path)
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["status"] == "completed" and saved["label"] == "Ours"
    assert saved["env_steps"] == 60 and saved["eval"]["episodes"] == 2
    stats = metrics["semdp"]
    assert stats["k"] == 10 and stats["train_high_level_steps"] == 60
    assert stats["train_low_level_steps"] == 600
    assert set(stats["time_split_s"]) == {"perception_s", "plan_s", "follow_s", "sim_s",
                                          "learning_and_overhead_s"}
    assert (tmp_path / "curves.png").stat().st_size > 0
    assert (tmp_path / "eval_episode.gif").stat().st_size > 0
    assert saved["gif_episode"]["high_level_steps"] == 20  # 200 env steps / k


@pytest.mark.parametrize(
    ("method", "label"),
    [("ours_wo_lag", "Ours w/o Lag"), ("ours_gt", "Ours w/ gt"),
     ("ppo_lag_sac", "PPO Lag + SAC")],
)
def test_semdp_ablation_methods_train(
    method: str, label: str, compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    algo = TINY_SAC if method != "ppo_lag_sac" else [
        "algo.update_iters=1", "algo.num_minibatches=2", "algo.hidden_sizes=[16,16]"]
    cfg = compose_train("experiment=semdp_ablations", f"method={method}", "robot=mass",
                        "budget=ci", *TINY_SEMDP, *algo, "env.post_train=null")
    metrics = run(cfg, tmp_path)
    assert metrics["status"] == "completed" and metrics["label"] == label


def test_semdp_point_push1_config_trains_under_budget_ci(
    compose_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    cfg = compose_train("algo=sac", "env=semdp_point_push1", *TINY_SEMDP, *TINY_SAC,
                        "env.post_train=null")
    metrics = run(cfg, tmp_path)
    assert metrics["status"] == "completed" and metrics["env_steps"] == 60
