"""``semdp-bench sims`` runs end to end on a tiny budget and writes its CSV."""

from __future__ import annotations

import csv

from semdp.benchmarks import sims as bench


def test_bench_sims_writes_one_row_per_env(tmp_path, capsys) -> None:
    out = tmp_path / "sims.csv"
    bench.main(["--steps", "40", "--num-envs", "2", "--robots", "mass", "--tasks", "goal",
                "push", "--no-async", "--csv", str(out)])  # fmt: skip
    rows = list(csv.DictReader(out.open()))
    assert [r["env"] for r in rows] == ["sims/SafetyMassGoal1-v0", "sims/SafetyMassPush1-v0"]
    assert all(float(r["single_steps_per_s"]) > 0 and float(r["sync_steps_per_s"]) > 0
               for r in rows)  # fmt: skip
    assert "| sims/SafetyMassPush1-v0 |" in capsys.readouterr().out


def test_bench_sims_calibration_table(capsys) -> None:
    bench.main(["--calibration"])
    text = capsys.readouterr().out
    assert "| Point speed | (0.05, 0.0) | 1.500 | 1.500 |" in text
    assert "Car yaw rate" in text
