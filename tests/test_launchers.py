"""Scale-out launchers for real: a 2-job ``budget=ci`` sweep through a Ray cluster this test
starts on the loopback address (``hydra/launcher=cluster_ray``) and through submitit's local
executor (``hydra/launcher=submitit_local``). The commands are those of docs/scale-out.md.

Both need the optional extras, which ``.[dev]`` installs (the README's test command); a missing
extra fails here rather than skipping.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _script(name: str) -> str:
    """A console script of this environment (beside the interpreter, else on PATH)."""
    path = BIN / name
    return str(path) if path.is_file() else (shutil.which(name) or name)
SWEEP = ["algo=ppo_lag", "env=point_goal1", "budget=ci", "seed=0,1"]
#: One machine: Ray resolves 127.0.0.1 to the host's routable address unless this is 0.
LOOPBACK_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _sweep(sweep_dir: Path, *launcher: str, env: dict[str, str] | None = None) -> float:
    """Run the 2-job sweep; check both run directories; return its wall time."""
    start = time.perf_counter()
    proc = subprocess.run(
        [_script("semdp-train"), "-m", *SWEEP, *launcher, f"hydra.sweep.dir={sweep_dir}"],
        cwd=REPO, text=True, capture_output=True, timeout=600, env={**os.environ, **(env or {})},
    )
    wall = time.perf_counter() - start
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    runs = sorted(p.name for p in sweep_dir.iterdir() if p.is_dir() and p.name[0].isdigit())
    assert runs == ["0_ppo_lag_point_goal1_s0", "1_ppo_lag_point_goal1_s1"]
    for run in runs:
        metrics = json.loads((sweep_dir / run / "metrics.json").read_text())
        assert metrics["status"] == "completed", metrics
        assert metrics["seed"] == int(run[-1])
        with (sweep_dir / run / "progress.csv").open(newline="") as f:
            rows = list(csv.DictReader(f))
        assert [int(r["epoch"]) for r in rows] == [1, 2, 3, 4]
        assert int(rows[-1]["env_steps"]) == 1600
    print(f"{launcher[0]}: 2-job ci sweep in {wall:.1f} s")
    return wall


def test_submitit_local_launcher_runs_a_two_job_ci_sweep(tmp_path: Path) -> None:
    _sweep(tmp_path / "sweep", "hydra/launcher=submitit_local")


def _wait_for(log: Path, text: str, proc: subprocess.Popen[bytes], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in log.read_text(errors="replace"):
            return
        if proc.poll() is not None:
            break
        time.sleep(0.5)
    pytest.fail(f"ray start did not report {text!r}:\n{log.read_text(errors='replace')[-3000:]}")


def test_ray_launcher_runs_a_two_job_ci_sweep_on_a_local_cluster(tmp_path: Path) -> None:
    port = _free_port()
    # A short temp dir: Ray's socket paths must stay under 107 characters.
    temp_dir = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))
    log = tmp_path / "ray_start.log"
    env = {**os.environ, **LOOPBACK_ENV}
    with log.open("wb") as out:
        head = subprocess.Popen(
            [_script("ray"), "start", "--head", "--block", "--node-ip-address=127.0.0.1",
             f"--port={port}", "--num-cpus=2", "--include-dashboard=false",
             "--disable-usage-stats", f"--temp-dir={temp_dir}"],
            stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True,
        )
    try:
        _wait_for(log, "Ray runtime started", head, timeout=120)
        _sweep(tmp_path / "sweep", "hydra/launcher=cluster_ray",
               f"hydra.launcher.ray.init.address=127.0.0.1:{port}", env=LOOPBACK_ENV)
    finally:
        # SIGTERM to `ray start --block` drains the node and ends every process it started;
        # its own process group is killed only if that does not happen in time.
        head.send_signal(signal.SIGTERM)
        try:
            head.wait(timeout=90)
        except subprocess.TimeoutExpired:
            os.killpg(head.pid, signal.SIGKILL)
            head.wait(timeout=30)
        shutil.rmtree(temp_dir, ignore_errors=True)
