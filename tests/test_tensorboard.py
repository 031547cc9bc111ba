"""TensorBoard mirror of ``progress.csv`` (docs/training.md, "Run directory") and the per-epoch
SEMDP time split: real ``budget=ci`` trainings read back with TensorBoard's EventAccumulator,
and the logger's resume rules on small synthetic CSVs."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from omegaconf import OmegaConf
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from semdp.cli.run_logging import tensorboard_enabled
from semdp.common.logger import (
    TIME_SPLIT_COLUMNS,
    TIMING_COLUMNS,
    ProgressCSV,
    TensorBoardRows,
    run_logging,
)

REPO = Path(__file__).resolve().parents[1]


def _train(run_dir: Path, *overrides: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "semdp.cli.train", *overrides, f"hydra.run.dir={run_dir}"],
        cwd=REPO, text=True, capture_output=True, timeout=600,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]


def _rows(run_dir: Path) -> list[dict[str, str]]:
    with (run_dir / "progress.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def _scalars(run_dir: Path) -> dict[str, list[tuple[int, float]]]:
    acc = EventAccumulator(str(run_dir), size_guidance={"scalars": 0})
    acc.Reload()
    return {tag: [(e.step, e.value) for e in acc.Scalars(tag)] for tag in acc.Tags()["scalars"]}


def _assert_mirrored(run_dir: Path) -> dict[str, list[tuple[int, float]]]:
    """Every non-empty progress.csv cell is a scalar at step env_steps with the same value."""
    rows, scalars = _rows(run_dir), _scalars(run_dir)
    filled = {c for r in rows for c, v in r.items() if v != ""}
    assert filled == set(scalars), (filled ^ set(scalars))
    for column in filled:
        expected = [(int(r["env_steps"]), float(r[column])) for r in rows if r[column] != ""]
        got = scalars[column]
        assert [s for s, _ in got] == [s for s, _ in expected], column
        # event files store float32
        np.testing.assert_array_equal(np.float32([v for _, v in got]),
                                      np.float32([v for _, v in expected]), err_msg=column)
    return scalars


def test_ppo_lag_ci_run_mirrors_every_progress_scalar_to_tensorboard(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    _train(run_dir, "algo=ppo_lag", "env=point_goal1", "budget=ci")
    assert list(run_dir.glob("events.out.tfevents.*"))
    scalars = _assert_mirrored(run_dir)
    assert [s for s, _ in scalars["lagrange_multiplier"]] == [400, 800, 1200, 1600]
    assert {"cost_threshold", "eval_return", "eval_cost", "loss_pi", "fps"} <= set(scalars)


def test_semdp_ci_run_logs_its_time_split_every_epoch(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    _train(run_dir, "experiment=semdp", "budget=ci")
    rows = _rows(run_dir)
    assert len(rows) == 4
    walls = [0.0] + [float(r["wall_time_s"]) for r in rows]
    for row, epoch_wall in zip(rows, np.diff(walls), strict=True):
        parts = [float(row[c]) for c in TIME_SPLIT_COLUMNS]
        assert all(p >= 0 for p in parts) and float(row["time_plan_s"]) > 0
        assert sum(parts) == pytest.approx(epoch_wall, rel=1e-6, abs=1e-6)
    scalars = _assert_mirrored(run_dir)
    assert set(TIME_SPLIT_COLUMNS) <= set(scalars)


def test_tensorboard_key_switches_the_mirror_off() -> None:
    assert not tensorboard_enabled(OmegaConf.create({"tensorboard": False}))
    assert tensorboard_enabled(OmegaConf.create({"tensorboard": True}))
    assert set(TIME_SPLIT_COLUMNS) <= set(TIMING_COLUMNS)


class _Source:
    columns = ("extra",)

    def start(self) -> None:
        self.n = 0

    def values(self, row: Any) -> dict[str, float]:
        self.n += 1
        return {"extra": float(self.n)}


def test_resume_keeps_old_rows_adds_new_columns_and_purges_later_tensorboard_steps(
    tmp_path: Path,
) -> None:
    path = tmp_path / "progress.csv"
    with run_logging(sink_factories=[TensorBoardRows]):
        first = ProgressCSV(path)
        for epoch in range(1, 5):
            first.write({"epoch": epoch, "env_steps": 100 * epoch, "ep_return": float(epoch)})
    # resumed at epoch 2, now with a source column the first session did not have
    with run_logging([_Source()], [TensorBoardRows]):
        second = ProgressCSV(path, keep_epochs=2)
        assert second.sinks[0].purge_step == 201
        for epoch in (3, 4):
            second.write({"epoch": epoch, "env_steps": 100 * epoch, "ep_return": -1.0 * epoch})
    rows = list(csv.DictReader(path.open(newline="")))
    assert [r["epoch"] for r in rows] == ["1", "2", "3", "4"]
    assert [r["extra"] for r in rows] == ["", "", "1.0", "2.0"]
    assert [r["ep_return"] for r in rows] == ["1.0", "2.0", "-3.0", "-4.0"]
    assert _scalars(tmp_path)["ep_return"] == [(100, 1.0), (200, 2.0), (300, -3.0), (400, -4.0)]


def test_outside_run_logging_the_csv_has_no_sinks(tmp_path: Path) -> None:
    csv_file = ProgressCSV(tmp_path / "progress.csv")
    csv_file.write({"epoch": 1, "env_steps": 10})
    assert csv_file.sinks == [] and not list(tmp_path.glob("events.out.tfevents.*"))
