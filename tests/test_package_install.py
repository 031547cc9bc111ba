"""The project installs as a package (a wheel, not an editable checkout): the apps find their
Hydra configs inside the installed package and run from any directory."""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run(args, cwd=cwd, env=env, text=True, capture_output=True,
                          timeout=timeout, check=False)
    assert done.returncode == 0, f"{args}: {done.stdout[-1500:]}\n{done.stderr[-3000:]}"
    return done


def test_a_wheel_runs_the_apps_from_another_directory(tmp_path: Path) -> None:
    pytest.importorskip("setuptools")  # the wheel is built without an isolated environment
    source = tmp_path / "source"  # a copy: the build writes build/ and *.egg-info in the tree
    shutil.copytree(ROOT, source, symlinks=True, ignore=shutil.ignore_patterns(
        ".git", "outputs", "build", "dist", "*.egg-info", ".venv", "__pycache__"))
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", str(dist), str(source)], cwd=tmp_path)
    wheel = next(dist.glob("semdp-*.whl"))
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], cwd=tmp_path)
    python = venv / "bin" / "python"
    # the dependencies: this environment's site-packages, after the venv's own (a plain path
    # entry: the editable install's import hook there is not loaded, so the wheel is imported)
    purelib = _run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                   cwd=tmp_path).stdout.strip()
    Path(purelib, "dependencies.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    _run([str(python), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)],
         cwd=tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = _run([str(python), "-c", "import semdp.paths as p; print(p.CONF_DIR)"], cwd=work)
    conf = Path(where.stdout.strip())
    assert conf.is_relative_to(venv) and (conf / "train.yaml").is_file()
    _run([str(venv / "bin" / "semdp-train"), "budget=ci", "total_steps=2000",
          "tensorboard=false", "hydra.run.dir=run"], cwd=work)
    assert (work / "run" / "metrics.json").is_file() and (work / "run" / "policy.pt").is_file()
    _run([str(venv / "bin" / "semdp-plan"), "plot=false", "hydra.run.dir=plan"], cwd=work)
