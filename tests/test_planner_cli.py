"""``semdp-plan`` (one planner and compare mode) and ``semdp-bench planner`` end to end."""

from __future__ import annotations

import csv
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from semdp.benchmarks import planner as planner_bench
from semdp.cli import plan as plan_app
from solvers.planner.compare import COLUMNS


def test_plan_cli_writes_png_and_result(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.cli.plan", "start=[0,0]", "subgoal=[2,1]",
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
        [sys.executable, "-m", "semdp.cli.plan", "obstacles=[[1,2,-1]]",
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
    # the plans' digest: the batch (one process, workers=1) plans exactly what the loop plans
    with open(tmp_path / "planner_summary.csv", newline="") as handle:
        digests = {row["variant"]: row["plans_sha256"] for row in csv.DictReader(handle)}
    assert all(len(d) == 64 for d in digests.values())
    assert digests["ipopt"] == digests["ipopt[batch3]"] and digests["lm"] == digests["lm[batch3]"]
    assert digests["ipopt"] != digests["lm"]
    assert len((tmp_path / "planner_results.csv").read_text().splitlines()) == 1 + 4 * 6
    batch = (tmp_path / "planner_batch.csv").read_text().splitlines()
    assert batch[0].startswith("variant,batch,workers,helpers,loop_ms,batch_ms") and len(batch) == 3


def test_plan_cli_compare_mode_writes_one_figure_and_one_table(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    names = ["ipopt", "lm", "lm_adaptive", "scp"]
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.cli.plan", f"backends=[{','.join(names)}]", "start=[0,0]",
         "subgoal=[2,1]", "obstacles=[[1,0.3],[0.4,-0.8]]", "repeats=1",
         f"hydra.run.dir={run_dir}"],
        capture_output=True, text=True, check=True, timeout=180,
    )
    for name in names:
        assert f"| {name} |" in completed.stdout
    for output in ("compare.png", "compare.json", "compare.csv"):
        assert f"wrote {run_dir / output}" in completed.stdout
    assert (run_dir / "compare.png").stat().st_size > 10_000
    payload = json.loads((run_dir / "compare.json").read_text())
    assert [row["name"] for row in payload["rows"]] == names
    assert payload["obstacles"] == [[1.0, 0.3, 0.0], [0.4, -0.8, 0.0]]
    with open(run_dir / "compare.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == list(COLUMNS) and [r["name"] for r in rows] == names
    for row in rows:
        assert row["fallback"] == "False" and row["reached_subgoal"] == "True"
        assert float(row["min_clearance"]) >= 0.5 - 1e-9
    assert rows[2]["backend"] == "lm"  # lm_adaptive is the LM backend with adaptive lambda


def test_plan_compare_applies_planner_overrides_to_every_planner(tmp_path: Path) -> None:
    cfg = OmegaConf.create({"backends": ["ipopt", "scp"], "backend": None, "start": [0, 0],
                            "subgoal": [2.5, 0], "obstacles": [[1.2, 0.0]], "repeats": 1,
                            "plot": False})
    comparison = plan_app.run_compare(cfg, tmp_path, ["problem.continuous=true"])
    for row in comparison.rows:
        assert row.min_clearance_continuous >= 0.5 - 1e-9 and not row.fallback
    assert (tmp_path / "compare.csv").is_file() and not (tmp_path / "compare.png").exists()
    assert plan_app.planner_overrides(
        ["planner=lm", "planner.problem.continuous=true", "start=[0,0]",
         "planner.problem.clearance=0.6"]
    ) == ["problem.continuous=true", "problem.clearance=0.6"]


def test_plan_cli_compare_unknown_backend_fails_with_one_line(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.cli.plan", "backends=[ipopt,teleport]",
         f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )
    assert completed.returncode == 1
    lines = completed.stderr.strip().splitlines()
    assert len(lines) == 1 and "unknown planner 'teleport'" in lines[0], completed.stderr
    assert "'lm_adaptive'" in lines[0]  # the options are listed
    assert not (tmp_path / "compare.json").exists()


def test_plan_cli_compare_malformed_obstacles_fail_with_one_line(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-m", "semdp.cli.plan", "backends=[lm,scp]", "obstacles=[[1,0.3],[0.4]]",
         f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )
    assert completed.returncode == 1
    lines = completed.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("semdp-plan: obstacles must be"), lines


def test_plan_bad_planner_setting_is_one_value_error(tmp_path: Path) -> None:
    node = plan_app.compose_planner("lm", ["problem.clearance=-1"])
    cfg = OmegaConf.create({"planner": node, "backend": None, "start": [0, 0],
                            "subgoal": [1, 0], "obstacles": [], "plot": False})
    with pytest.raises(ValueError, match=r"^planner: clearance must be a finite number >= 0"):
        plan_app.run(cfg, tmp_path)


def test_plans_sha256_hashes_waypoints_and_flags_in_order() -> None:
    import hashlib

    import numpy as np

    from solvers.planner import PlanResult

    def result(offset: float, status: str = "solved") -> PlanResult:
        waypoints = np.arange(6, dtype=float).reshape(3, 2) + offset
        return PlanResult(waypoints, np.zeros((3, 2)), True, status, False, False, 0.0,
                          float("inf"), float("inf"), 1, 0.0, "lm", True)

    plans = [result(0.0), result(1.0)]
    expected = hashlib.sha256()
    for plan in plans:
        expected.update(plan.waypoints.tobytes())
        expected.update(f"{plan.status}|True|False|False|False\n".encode())
    digest = planner_bench.plans_sha256(plans)
    assert digest == expected.hexdigest()  # the definition the recorded digests rely on
    assert planner_bench.plans_sha256(plans[::-1]) != digest
    assert planner_bench.plans_sha256([plans[0], result(1.0, "max_iter")]) != digest
    times_differ = [dataclasses.replace(p, solve_time_s=9.0) for p in plans]
    assert planner_bench.plans_sha256(times_differ) == digest


def test_plan_compare_reports_clearance_and_smoothness_budget_per_backend(tmp_path: Path) -> None:
    """``semdp-plan backends=[ipopt,lm] start=[0,0] subgoal=[2.5,1]
    obstacles=[[1,0.3],[0.4,-0.8],[1.8,1.2]]``: per backend the clearance and h_smooth against
    its budget sigma (Eq. 3.6); LM keeps the budget only as a penalty and exceeds it here."""
    cfg = OmegaConf.create({"backends": ["ipopt", "lm"], "backend": None, "start": [0, 0],
                            "subgoal": [2.5, 1], "obstacles": [[1, 0.3], [0.4, -0.8], [1.8, 1.2]],
                            "repeats": 1, "plot": False})
    comparison = plan_app.run_compare(cfg, tmp_path)
    table = comparison.table()
    assert "h_smooth / σ" in table and "min clearance waypoints (m)" in table
    ipopt, lm = comparison["ipopt"], comparison["lm"]
    assert ipopt.within_budget and not lm.within_budget and "(over, ×" in table
    with open(tmp_path / "compare.csv", newline="") as handle:
        rows = {row["name"]: row for row in csv.DictReader(handle)}
    for name in ("ipopt", "lm"):
        assert float(rows[name]["min_clearance"]) >= 0.5 - 1e-9
        assert float(rows[name]["smoothness_budget"]) == 0.048
    assert rows["ipopt"]["within_budget"] == "True" and rows["lm"]["within_budget"] == "False"


def test_plan_backend_node_knobs_are_overridable_and_validated(tmp_path: Path) -> None:
    node = plan_app.compose_planner("lm", ["backend.iterations=3", "backend.adaptive=true"])
    assert node.backend.iterations == 3 and node.backend.adaptive is True
    bad = plan_app.compose_planner("scp", ["backend.trust_region=0"])
    cfg = OmegaConf.create({"planner": bad, "backend": None, "start": [0, 0],
                            "subgoal": [1, 0], "obstacles": [], "plot": False})
    with pytest.raises(ValueError, match=r"^planner: trust_region must be a finite number > 0"):
        plan_app.run(cfg, tmp_path)
    with pytest.raises(ValueError, match="planner lm"):  # a knob of another backend
        plan_app.compose_planner("lm", ["backend.trust_region=0.5"])
