"""Same seed => the same learning curve, whatever the machine's load and thread count (every
run sets torch to ``torch_threads`` = 1 threads, and helper processes run one thread each).

Wall-clock columns (``wall_time_s``, ``fps``, ``time_*``) are excluded; every other column the
golden file has must match to 1e-9 relative (exact on machines of this project's kind).

The files in ``golden/`` were recorded on AMD processors; training's matrix products give
other last bits on Intel ones under every MKL branch (semdp/numerics.py), so an Intel machine
compares with ``golden/GenuineIntel/`` (recorded on an Intel Xeon with the same pins).
``SEMDP_RECORD_GOLDEN=1 pytest tests/test_golden_progress.py`` writes this vendor's files
(where the vendor has its own folder) instead of comparing.

* Files recorded before the config and module restructuring (commit d56383e), with the defaults
  changed since switched back to the recorded setting (the IPOPT rescue for the Point and the
  low-level safety filter, which the recording did not have; evaluations in one process; the
  critics' regression through autograd; the Point's tracking look-ahead, 0.2 m then).
* Files that pin today's defaults: PPO-Lag with the written-out derivatives and two evaluation
  processes, checked with every helper off (``loop=single``) and on (``loop=helpers``), which
  must give the same numbers; the SEMDP main job's pipelined loop (lockstep envs, a learner
  process) past ``learning_starts``, so the learner's updates are pinned too (with the filter's
  whole-bin LiDAR bound and the 0.2 m look-ahead it was recorded with).
"""

from __future__ import annotations

import csv
import math
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from omegaconf import DictConfig

from semdp.cli.train import run
from semdp.numerics import cpu_vendor

GOLDEN = Path(__file__).parent / "data" / "golden"
#: Vendors whose training gives other last bits than the AMD recordings: their own folder.
OWN_FOLDER = ("GenuineIntel",)


def golden_file(name: str, vendor: str) -> Path:
    """The golden file ``name`` for a processor of ``vendor``."""
    return GOLDEN / vendor / name if vendor in OWN_FOLDER else GOLDEN / name


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def _same(a: str, b: str) -> bool:
    if a == b:
        return True
    if not a or not b:
        return False
    return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)


def _is_clock(column: str) -> bool:
    """Wall-clock columns, and the record of which helpers ran (the numbers do not depend on it)."""
    return (column in ("wall_time_s", "fps", "rollout_helper", "critic_helper")
            or column.startswith("time_"))


@pytest.mark.parametrize(
    ("golden", "overrides"),
    [
        ("ppo_lag_point_goal1_ci_s0.csv",
         ["algo=ppo_lag", "env=point_goal1", "budget=ci", "seed=0", "eval_workers=1",
          "algo.gradients=autograd"]),
        ("semdp_ci_s0.csv", ["experiment=semdp", "budget=ci", "seed=0", "loop=sequential",
                             "robot.rescue_backend=null", "env.shield=null", "eval_workers=1",
                             "algo.hidden_sizes=[256,256]", "robot.lookahead=0.2"]),
        ("ppo_lag_point_goal1_ci_s0_written.csv",
         ["algo=ppo_lag", "env=point_goal1", "budget=ci", "seed=0", "loop=single",
          "eval_workers=2"]),
        ("ppo_lag_point_goal1_ci_s0_written.csv",
         ["algo=ppo_lag", "env=point_goal1", "budget=ci", "seed=0", "loop=helpers"]),
        ("semdp_pipelined_s0.csv",
         ["experiment=semdp", "budget=ci", "seed=0", "total_steps=2400",
          "algo.learning_starts=800", "tensorboard=false", "algo.hidden_sizes=[256,256]",
          "env.shield.lidar_bearing_bound=bin", "robot.lookahead=0.2"]),
    ],
    ids=["ppo_lag_d56383e", "semdp_sequential_d56383e", "ppo_lag_helpers_off",
         "ppo_lag_helpers_on", "semdp_pipelined"],
)
def test_progress_matches_golden(
    compose_train: Callable[..., DictConfig], tmp_path: Path, golden: str, overrides: list[str]
) -> None:
    run_dir = tmp_path / "run"
    cfg = compose_train(*overrides)
    if "loop=helpers" in overrides:  # the helper path, every epoch
        assert (cfg.algo.vectorization, cfg.algo.parallel_critics) == ("async", True)
    run(cfg, run_dir)
    path = golden_file(golden, cpu_vendor())
    if os.environ.get("SEMDP_RECORD_GOLDEN") == "1" and path.parent != GOLDEN:
        path.parent.mkdir(exist_ok=True)
        if not path.exists():
            shutil.copy(run_dir / "progress.csv", path)
    expected = _rows(path)
    actual = _rows(run_dir / "progress.csv")
    assert len(actual) == len(expected)
    if "loop=helpers" in overrides:  # progress.csv records the helpers taken
        assert all(r["rollout_helper"] == "1.0" and r["critic_helper"] == "1.0" for r in actual)
    if "loop=single" in overrides:
        assert all(r["rollout_helper"] == "0.0" and r["critic_helper"] == "0.0" for r in actual)
    for row_expected, row_actual in zip(expected, actual, strict=True):
        for column, value in row_expected.items():
            if _is_clock(column):
                continue
            assert column in row_actual, f"column {column} missing"
            assert _same(value, row_actual[column]), (
                f"epoch {row_expected['epoch']} {column}: golden {value!r}, "
                f"now {row_actual[column]!r}"
            )


def test_amd_and_unknown_vendors_compare_with_the_amd_recordings() -> None:
    assert golden_file("x.csv", "AuthenticAMD") == GOLDEN / "x.csv"
    assert golden_file("x.csv", "") == GOLDEN / "x.csv"
    assert golden_file("x.csv", "GenuineIntel") == GOLDEN / "GenuineIntel" / "x.csv"
    for name in ("ppo_lag_point_goal1_ci_s0.csv", "ppo_lag_point_goal1_ci_s0_written.csv",
                 "semdp_ci_s0.csv", "semdp_pipelined_s0.csv"):
        for vendor in ("AuthenticAMD", *OWN_FOLDER):
            assert golden_file(name, vendor).is_file(), (name, vendor)
