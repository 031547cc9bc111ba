"""The README's Python snippet runs as a new user runs it: a fresh interpreter with torch's
default threads (the helper processes fork after torch started its thread pool)."""

from __future__ import annotations

import csv
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _snippet() -> str:
    text = (ROOT / "README.md").read_text()
    found = re.search(r"<!-- python-snippet -->\n```python\n(.*?)```", text, re.S)
    assert found, "README.md has no <!-- python-snippet --> block"
    return found.group(1)


def _run(code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, text=True,
                          capture_output=True, timeout=600, check=False)


def test_the_readme_snippet_trains_two_epochs(tmp_path: Path) -> None:
    done = _run(_snippet(), tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["completed", "8000"]
    rows = list(csv.DictReader((tmp_path / "runs/ppo_lag_point_goal1/progress.csv").open()))
    assert [r["epoch"] for r in rows] == ["1", "2"]


def test_the_snippet_with_every_helper_and_two_torch_threads(tmp_path: Path) -> None:
    """The case that hung: torch's pool started with two threads, then the rollout and critic
    helpers forked; pinned here whatever the machine's cores and load."""
    if "fork" not in __import__("multiprocessing").get_all_start_methods():
        pytest.skip("needs fork")
    code = _snippet().replace(
        "from semdp.algos import PPOLag\n",
        "import torch\ntorch.set_num_threads(2)\ntorch.ones(256, 256) @ torch.ones(256, 256)\n"
        "from semdp.algos import PPOLag\nfrom semdp.algos.speedups import HelperRunners\n").replace(
        "seed=0, steps_per_epoch=4000,",
        "seed=0, steps_per_epoch=4000, runners=HelperRunners('async', True),")
    assert "HelperRunners('async', True)" in code
    done = _run(code, tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    rows = list(csv.DictReader((tmp_path / "runs/ppo_lag_point_goal1/progress.csv").open()))
    assert [(r["rollout_helper"], r["critic_helper"]) for r in rows] == [("1.0", "1.0")] * 2
