"""End to end: every experiment preset at the `ci` budget, then `semdp-report` on its sweep
directory. The launcher sweeps (submitit, Ray) are in the default suite:
tests/test_launchers.py.

    python -m pytest -m slow tests/test_experiments_slow.py -q
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
SEMDP_METHODS = ["Ours", "CPO", "PPO Lag", "TRPO Lag"]
#: preset -> (report columns, report envs, extra report files): names as a reader expects them
#: (``curves_<env>.png`` with spaces and slashes as ``_``).
EXPECTED: dict[str, tuple[list[str], list[str], list[str]]] = {
    "sp_driving": (["PPO-Lag", "SP-PPO-Lag"],
                   [f"{task} {v} m/s" for task in ("Circle", "Trajectory") for v in (2, 6)], []),
    "sp_safety_gym": (["PPO-Lag", "SP-PPO-Lag"],
                      [f"Point{t}{lv}" for t in ("Goal", "Button", "Push") for lv in (1, 2)], []),
    "semdp_push": (SEMDP_METHODS, ["MassPush1", "PointPush1", "CarPush1"], []),
    "semdp_ablations": (["Ours", "PPO Lag + SAC", "SAC + PPO Lag", "Ours w/ gt", "Ours w/o Lag"],
                        ["MassPush1", "PointPush1", "CarPush1"], []),
    "semdp_tradeoff": (SEMDP_METHODS, ["PointPush1"], ["tradeoff_PointPush1.png"]),
    "semdp_goal": (SEMDP_METHODS, ["PointGoal1"], []),
    "transfer": (["Ours", "TRPO Lag"], ["PointPush1"], ["transfer_table.md"]),
}


def _cli(module: str, *args: str, timeout: int = 1500) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run([sys.executable, "-m", module, *args], cwd=REPO, text=True,
                          capture_output=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def _train(*overrides: str) -> None:
    _cli("semdp.cli.train", "-m", *overrides)


def read_table(path: Path) -> tuple[list[str], dict[tuple[str, str], list[str]]]:
    """Columns (methods) and rows {(env, metric): cells} of a semdp-report table.md."""
    columns: list[str] = []
    rows: dict[tuple[str, str], list[str]] = {}
    for line in path.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[:2] == ["env", "metric"]:
            columns = cells[2:]
        elif columns and len(cells) == len(columns) + 2 and cells[1] in ("reward", "cost"):
            rows[(cells[0], cells[1])] = cells[2:]
    return columns, rows


#: Robots whose SEMDP follower weights are committed .
ROBOTS = [r for r in ("mass", "point", "car")
          if r == "mass" or (REPO / "semdp" / "embedded" / "weights" / f"{r}.pt").is_file()]


@pytest.mark.parametrize("name", list(EXPECTED))
def test_preset_ci_sweep_and_report(name: str, tmp_path: Path) -> None:
    sweep = tmp_path / name
    methods, envs, extra = EXPECTED[name]
    overrides = []
    if name in ("semdp_push", "semdp_ablations"):  # robots without follower weights can't run
        overrides = [f"robot={','.join(ROBOTS)}"]
        envs = [env for env in envs if env[:-5].lower() in ROBOTS]
    _train(f"experiment={name}", "budget=ci", f"hydra.sweep.dir={sweep}", *overrides)
    if name == "transfer":
        _cli("semdp.experiments.transfer", "table", str(sweep))
    _cli("semdp.cli.report", str(sweep))
    report = sweep / "report"
    columns, rows = read_table(report / "table.md")
    assert sorted(columns) == sorted(methods)
    assert set(rows) == {(env, metric) for env in envs for metric in ("reward", "cost")}
    for env in envs:
        assert (report / f"curves_{env.replace(' m/s', '_m_s').replace(' ', '_')}.png").is_file()
    for file in extra:
        assert (report / file).is_file()
    statuses = {}
    for path in sweep.rglob("metrics.json"):
        metrics = json.loads(path.read_text())
        statuses[path.parent.name] = metrics["status"]
        if metrics["status"] == "completed" and name.startswith("semdp"):
            assert metrics["label"] in methods
    # Every run completes, except "SAC + PPO Lag" while its PPO-Lag follower weights are not
    # committed (conf/robot/<robot>.yaml's ppo_lag_follower names them; made by semdp_low_ppo_lag).
    weights = REPO / "semdp" / "embedded" / "weights"
    missing = [r for r in ROBOTS if not (weights / f"{r}_ppo_lag.pt").is_file()]
    allowed = {"sac_ppo_lag"} if missing else set()
    failed = {run for run, status in statuses.items() if status != "completed"}
    assert {run.split("_", 1)[1].rsplit("_", 2)[0] for run in failed} <= allowed, statuses
    if name == "semdp_tradeoff":
        ours = [json.loads(p.read_text()) for p in sweep.rglob("metrics.json")]
        points = [m["tradeoff"] for m in ours if m.get("label") == "Ours"]
        assert points and [p["clearance"] for p in points[0]] == [0.1, 0.25, 0.5, 0.75]
