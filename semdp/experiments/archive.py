"""Keep a sweep's light run files beside its reference, so that the reference can be rebuilt
and extended on another machine (outputs/reference/README.md: the layout).

Sweep directories live in git-ignored scratch under ``outputs/``, and a new machine starts
without them: a reference folder built from them could not be rebuilt with more seeds later.
The report needs only each run's ``metrics.json``, ``progress.csv`` and ``config.yaml`` (the
run-directory contract of docs/design.md) and the sweep's ``multirun.yaml`` (its command), a
few hundred kB per run without checkpoints or event files; the trained policy (``policy.pt``, a
few hundred kB more) is kept too, so ``semdp-eval`` re-evaluates a kept run, and so is
``eval.json`` where a run has one (a ``semdp-eval`` result the reference records).
:func:`archive_sweep` copies those (and ``.hydra/overrides.yaml``) and writes ``timing.json``:
the sweep's start and each run's finish time, which file times do not keep through a git
checkout.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from semdp.reporting.runs import METRICS_NAME, find_run_dirs

KEPT_RUN_FILES: tuple[str, ...] = (METRICS_NAME, "progress.csv", "config.yaml",
                                   ".hydra/overrides.yaml", "policy.pt", "eval.json")
MULTIRUN_NAME = "multirun.yaml"
TIMING_NAME = "timing.json"


def read_timing(sweep_dir: Path) -> dict[str, Any]:
    """The sweep's start and its runs' finish times (POSIX seconds).

    From ``timing.json`` in an archived sweep; otherwise from the files' modification times:
    ``multirun.yaml`` for the start (``None`` without one) and each run's ``metrics.json`` for
    its finish. Returns ``{"start": float | None, "finished": {run path relative to the sweep:
    float}}``.
    """
    sweep_dir = Path(sweep_dir)
    stored = sweep_dir / TIMING_NAME
    if stored.is_file():
        timing = json.loads(stored.read_text())
        return {"start": timing.get("start"), "finished": dict(timing.get("finished", {}))}
    multirun = sweep_dir / MULTIRUN_NAME
    finished = {}
    for run in find_run_dirs(sweep_dir):
        metrics = run / METRICS_NAME
        if metrics.is_file():
            finished[run.relative_to(sweep_dir).as_posix()] = metrics.stat().st_mtime
    return {"start": multirun.stat().st_mtime if multirun.is_file() else None,
            "finished": finished}


def archive_sweep(sweep_dir: Path, dest: Path) -> int:
    """Copy the light files of every run below ``sweep_dir`` into ``dest``; returns the count.

    ``dest`` keeps the sweep's layout (run directories at the same relative paths) and gets
    ``timing.json``. An earlier archive at ``dest`` is replaced; archiving a directory onto
    itself does nothing.

    Raises:
        ValueError: ``sweep_dir`` is not a directory, one of the two lies inside the other, or
            ``dest`` exists, is not empty and is not an archive (no ``timing.json``).
    """
    source, target = Path(sweep_dir).resolve(), Path(dest).resolve()
    if not source.is_dir():
        raise ValueError(f"not a directory: {sweep_dir}")
    runs = find_run_dirs(source)
    if source == target:
        return len(runs)
    if source.is_relative_to(target) or target.is_relative_to(source):
        raise ValueError(f"cannot archive {sweep_dir} into {dest}: one lies inside the other")
    if target.exists() and any(target.iterdir()):
        if not (target / TIMING_NAME).is_file():
            raise ValueError(f"{dest} exists and is not an archive of a sweep (no {TIMING_NAME})")
        shutil.rmtree(target)
    timing = read_timing(source)
    target.mkdir(parents=True, exist_ok=True)
    if (source / MULTIRUN_NAME).is_file():
        shutil.copy2(source / MULTIRUN_NAME, target / MULTIRUN_NAME)
    for run in runs:
        relative = run.relative_to(source)
        (target / relative).mkdir(parents=True, exist_ok=True)
        for name in KEPT_RUN_FILES:
            if (run / name).is_file():
                (target / relative / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(run / name, target / relative / name)
    (target / TIMING_NAME).write_text(json.dumps(timing, indent=1, sort_keys=True) + "\n")
    return len(runs)
