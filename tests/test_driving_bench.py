"""``semdp-bench driving`` runs end to end and writes its CSV (App. A.2)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from semdp.benchmarks import driving


def test_driving_benchmark_writes_speed_and_controller_rows(tmp_path: Path) -> None:
    out = tmp_path / "driving.csv"
    driving.main(["steps=300", "repeats=1", "episodes=1", "speeds=[2,6]", f"out={out}"])
    rows = list(csv.DictReader(out.open()))
    speed = [r for r in rows if r["section"] == "speed"]
    controller = {(r["env_id"], float(r["desired_speed"])): r for r in rows
                  if r["section"] == "controller"}
    assert len(speed) == 4 and all(float(r["steps_per_s"]) > 0 for r in speed)
    assert set(controller) == {(e, v) for e in driving.ENV_IDS for v in (2.0, 6.0)}
    assert float(controller["sims/DriveCircle-v0", 2.0]["cost_mean"]) == 0.0
    assert float(controller["sims/DriveCircle-v0", 6.0]["cost_mean"]) > 0.0


def test_driving_benchmark_rejects_unknown_arguments() -> None:
    with pytest.raises(SystemExit, match="unknown argument 'stepz=3'"):
        driving.main(["stepz=3"])
