"""The scripts of examples/ run as a user runs them, each in a fresh interpreter."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(name: str, cwd: Path) -> str:
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    env = dict(os.environ, PYTHONPATH=path)
    done = subprocess.run([sys.executable, str(ROOT / "examples" / name)], cwd=cwd, env=env,
                          text=True, capture_output=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_plan_compare(tmp_path: Path) -> None:
    out = _run("plan_compare.py", tmp_path)
    assert "ipopt: reached subgoal False, h_smooth 0.048" in out
    assert "lm: reached subgoal True, h_smooth 0.120" in out
    assert (tmp_path / "plan_compare.png").stat().st_size > 10_000


def test_train_ppo_lag(tmp_path: Path) -> None:
    out = _run("train_ppo_lag.py", tmp_path)
    assert out.startswith("completed after 8000 env steps")
    assert (tmp_path / "runs" / "ppo_lag_point_goal1" / "policy.pt").is_file()


def test_evaluate_zoo_policy(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    out = _run("evaluate_zoo_policy.py", tmp_path)
    lines = [line for line in out.splitlines() if line.startswith("seed ")]
    assert len(lines) == 2
    for line in lines:  # the recorded episodes, reproduced
        now = line.split("return ")[1].split(" (recorded ")
        assert now[0] == now[1].split(")")[0]
