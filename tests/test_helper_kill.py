"""``kill -9`` of a helper process during ``semdp-train``: the run stops with one line naming the
helper and the resume command, its last checkpoint intact, and ``resume=`` continues to the
numbers of an uninterrupted run (every helper kind of a training run)."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PPO_LAG = ["algo=ppo_lag", "env=point_goal1", "budget=ci", "total_steps=48000",
           "budget.steps_per_epoch=4000", "eval_every=0", "final_eval_episodes=4",
           "tensorboard=false"]
CASES = {
    "semdp-rollout": [*PPO_LAG, "loop=helpers", "eval_workers=1"],
    "semdp-critics": [*PPO_LAG, "loop=helpers", "eval_workers=1"],
    "semdp-eval": [*PPO_LAG, "loop=single", "eval_workers=2", "eval_every=1",
                   "eval_episodes=4"],
    "semdp-learner": ["experiment=semdp", "budget=ci", "total_steps=4000",
                      "algo.learning_starts=800", "checkpoint_every=1", "tensorboard=false"],
}
pytestmark = pytest.mark.skipif(not Path("/proc/self/comm").exists(),
                                reason="finds helpers by their Linux process name")


def _train(run_dir: Path, *overrides: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "semdp.cli.train", *overrides, f"hydra.run.dir={run_dir}"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _descendant(pid: int, name: str) -> int | None:
    children: dict[int, list[int]] = {}
    names: dict[int, str] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        child = int(stat.parent.name)
        names[child] = text[text.index("(") + 1 : text.rindex(")")]
        children.setdefault(int(text.rsplit(")", 1)[1].split()[1]), []).append(child)
    todo = list(children.get(pid, []))
    while todo:
        child = todo.pop()
        if names.get(child) == name:
            return child
        todo.extend(children.get(child, []))
    return None


def _values(run_dir: Path) -> list[dict[str, str]]:
    skip = ("wall_time_s", "fps", "rollout_helper", "critic_helper")
    with (run_dir / "progress.csv").open() as f:
        return [{k: v for k, v in row.items() if k not in skip and not k.startswith("time_")}
                for row in csv.DictReader(f)]


@pytest.mark.slow
@pytest.mark.parametrize("helper", sorted(CASES))
def test_kill_9_of_a_helper_stops_the_run_with_one_line_and_resume_is_identical(
    helper: str, tmp_path: Path
) -> None:
    overrides = CASES[helper]
    reference = _train(tmp_path / "reference", *overrides)
    assert reference.wait(600) == 0, reference.stderr.read() if reference.stderr else ""
    victim_dir = tmp_path / "victim"
    victim = _train(victim_dir, *overrides)
    checkpoint = victim_dir / "checkpoints" / "last.pt"
    deadline = time.monotonic() + 300
    target = None
    while time.monotonic() < deadline and victim.poll() is None:
        target = _descendant(victim.pid, helper) if checkpoint.exists() else None
        if target is not None:
            break
        time.sleep(0.02)
    assert target is not None, f"no {helper} process seen after the first checkpoint"
    os.kill(target, signal.SIGKILL)
    _, err = victim.communicate(timeout=120)
    assert victim.returncode == 1
    last = err.strip().splitlines()[-1]
    assert last == (f"semdp-train: helper process {helper} (pid {target}) died (killed by "
                    f"SIGKILL); the last checkpoint is kept, continue with: semdp-train "
                    f"resume={victim_dir}"), err[-2000:]
    resumed = _train(tmp_path / "unused", f"resume={victim_dir}")
    assert resumed.wait(600) == 0, resumed.stderr.read() if resumed.stderr else ""
    assert _values(victim_dir) == _values(tmp_path / "reference")
    final = [json.loads((d / "metrics.json").read_text())["eval"]
             for d in (victim_dir, tmp_path / "reference")]
    assert final[0] == final[1] and final[0]["episodes"] > 0
