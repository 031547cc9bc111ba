"""``semdp-plan`` and ``semdp-bench planner`` end to end (issue 3 deliverables 7-8)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from semdp.benchmarks import planner as planner_bench


def test_plan_cli_writes_png_and_result(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.plan", "start=[0,0]", "subgoal=[2,1]",
         "obstacles=[[1,0.3,0],[0.4,-0.8,0.1]]", "backend=scp", f"hydra.run.dir={run_dir}"],
        capture_output=True, text=True, check=True, timeout=120,
    )
    assert "feasible=True" in completed.stdout
    assert f"wrote {run_dir / 'plan.png'}" in completed.stdout
    assert (run_dir / "plan.png").stat().st_size > 10_000
    result = json.loads((run_dir / "plan.json").read_text())
    assert result["backend"] == "scp" and len(result["waypoints"]) == 30


def test_plan_cli_reports_bad_input_without_traceback(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.plan", "obstacles=[[1,2,-1]]",
         f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )
    assert completed.returncode != 0
    assert "radii must be >= 0" in completed.stderr and "Traceback" not in completed.stderr


def test_planner_benchmark_writes_table_and_csv(tmp_path: Path, capsys) -> None:
    planner_bench.main(["backends=[ipopt,lm]", "n=6", "seed=1", "batch=3", "workers=1",
                        f"out={tmp_path}"])
    printed = capsys.readouterr().out
    assert "| ipopt |" in printed and "| lm[batch3] |" in printed
    assert "| ipopt[batch3] | 3 | 1 (0) |" in printed  # the batch-vs-loop table
    summary = (tmp_path / "planner_summary.csv").read_text().splitlines()
    assert summary[0].startswith("variant,n,median_ms,mean_ms") and len(summary) == 5
    assert len((tmp_path / "planner_results.csv").read_text().splitlines()) == 1 + 4 * 6
    batch = (tmp_path / "planner_batch.csv").read_text().splitlines()
    assert batch[0].startswith("variant,batch,workers,helpers,loop_ms,batch_ms") and len(batch) == 3
