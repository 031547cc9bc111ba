"""Turn a finished sweep into a committed reference folder (layout: outputs/reference/README.md).

    python -m semdp.experiments.reference <sweep dir> outputs/reference/<preset> [--order ...]
    python -m semdp.experiments.reference <sweep s0> <sweep s1> outputs/reference/<preset>
    python -m semdp.experiments.reference <sweeps> outputs/reference/<preset> --keep-runs

Writes the ``semdp-report`` table and figures into the folder (no checkpoints) and
``COMMAND.md``: the exact command (from the sweep's ``multirun.yaml``), the sweep's wall time
(first job start to last ``metrics.json``), the summed per-run training wall time, the number
of runs and their status, the machine, and the table. With ``--keep-runs`` the runs' light
files go into ``<folder>/runs/`` too (:mod:`semdp.experiments.archive`), so that the folder
can be rebuilt, or extended with more seeds, from a fresh clone.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import shutil
import time
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from semdp.experiments.archive import archive_sweep, read_timing
from semdp.numerics import cpuinfo_field
from semdp.reporting.tables import parse_compare, parse_marks, write_report

RUNS_DIR = "runs"


def _cpu_model() -> str:
    """The processor's model name (Linux), or the architecture."""
    return cpuinfo_field("model name") or platform.processor() or platform.machine()


def this_machine() -> str:
    """The machine the reference is built on: cores, processor, architecture, Python and the
    CPU kernels' pin (:mod:`semdp.numerics`: MKL's code path decides the last bits)."""
    pin = os.environ.get("MKL_CBWR", "unpinned")
    return (f"{os.cpu_count()} logical CPUs ({_cpu_model()}, {platform.machine()}), "
            f"{platform.python_implementation()} {platform.python_version()}, "
            f"MKL_CBWR={pin}")


def sweep_command(sweep_dir: Path) -> str:
    """``semdp-train -m <overrides>`` as recorded in ``multirun.yaml``."""
    path = sweep_dir / "multirun.yaml"
    if not path.is_file():
        raise ValueError(f"{sweep_dir} has no multirun.yaml (not a Hydra sweep directory)")
    cfg = OmegaConf.load(path)
    overrides = [*cfg.hydra.overrides.task, *cfg.hydra.overrides.hydra]
    overrides = [o for o in overrides
                 if not o.startswith(("hydra.sweep.dir=", "hydra.mode="))]
    return "semdp-train -m " + " ".join(shlex.quote(str(o)) for o in overrides)


def _recorded_command(sweep_dir: Path) -> str:
    """:func:`sweep_command`, or a comment for a folder of runs collected by hand."""
    if (sweep_dir / "multirun.yaml").is_file():
        return sweep_command(sweep_dir)
    return f"# {sweep_dir.name}: run directories collected from several commands (no multirun.yaml)"


def sweep_summary(sweep_dir: Path) -> dict[str, Any]:
    """Run count, statuses, summed run wall time and the sweep's wall time (seconds).

    Times come from :func:`~semdp.experiments.archive.read_timing`: an archived sweep's
    ``timing.json``, else the files' modification times.
    """
    sweep_dir = Path(sweep_dir)
    metrics_files = sorted(sweep_dir.rglob("metrics.json"))
    metrics_files = [p for p in metrics_files if "report" not in p.parts]
    timing = read_timing(sweep_dir)
    statuses: dict[str, int] = {}
    run_wall = 0.0
    finishes = []
    for path in metrics_files:
        metrics = json.loads(path.read_text())
        statuses[metrics.get("status", "?")] = statuses.get(metrics.get("status", "?"), 0) + 1
        run_wall += float(metrics.get("wall_time_s") or 0.0)
        run = path.parent.relative_to(sweep_dir).as_posix()
        finishes.append(float(timing["finished"].get(run, path.stat().st_mtime)))
    end = max(finishes, default=time.time())
    # Without multirun.yaml (runs collected from several sweeps) the summed run time stands in.
    sweep_wall = end - timing["start"] if timing["start"] is not None else run_wall
    return {"runs": len(metrics_files), "statuses": statuses, "run_wall_s": run_wall,
            "sweep_wall_s": sweep_wall,
            "finished": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(end))}


def combined_summary(sweep_dirs: list[Path]) -> dict[str, Any]:
    """:func:`sweep_summary` of several sweeps: counts and times added, the last finish."""
    parts = [sweep_summary(sweep) for sweep in sweep_dirs]
    statuses: dict[str, int] = {}
    for part in parts:
        for status, count in part["statuses"].items():
            statuses[status] = statuses.get(status, 0) + count
    return {"runs": sum(p["runs"] for p in parts), "statuses": statuses,
            "run_wall_s": sum(p["run_wall_s"] for p in parts),
            "sweep_wall_s": sum(p["sweep_wall_s"] for p in parts),
            "finished": max(p["finished"] for p in parts)}


def keep_sweeps(sweeps: list[Path], runs_dir: Path) -> list[str]:
    """Archive each sweep into ``runs_dir/<its name>`` and return the names used.

    A sweep already inside ``runs_dir`` keeps its folder; another of the same name gets a
    ``_2``, ``_3`` ... suffix. Folders in ``runs_dir`` that are none of ``sweeps`` are removed,
    so that ``runs_dir`` holds exactly the runs the table was built from.
    """
    runs_dir = Path(runs_dir).resolve()
    names: dict[Path, str] = {}
    for sweep in sweeps:
        resolved = Path(sweep).resolve()
        if resolved.parent == runs_dir:
            names[resolved] = resolved.name
    for sweep in sweeps:
        resolved = Path(sweep).resolve()
        if resolved in names:
            continue
        name, index = resolved.name, 1
        while name in names.values():
            index += 1
            name = f"{resolved.name}_{index}"
        names[resolved] = name
    for resolved, name in names.items():
        archive_sweep(resolved, runs_dir / name)
    for stale in sorted(runs_dir.iterdir()) if runs_dir.is_dir() else []:
        if stale.name not in names.values():
            shutil.rmtree(stale) if stale.is_dir() else stale.unlink()
    return [names[Path(sweep).resolve()] for sweep in sweeps]


def write_reference(sweep_dir: Path | list[Path], out_dir: Path,
                    order: list[str] | None = None, note: str = "", command: str = "",
                    compare: tuple[str, str] | None = None, late: float = 0.0,
                    at: tuple[float, ...] = (), machine: str = "",
                    keep_runs: bool = False) -> Path:
    """Report + ``COMMAND.md`` into ``out_dir``; returns the ``COMMAND.md`` path.

    ``sweep_dir``: one sweep, or several reported together (their commands, from each
    ``multirun.yaml``, one per line; their run counts and wall times added). ``machine``: how
    the runs shared the machine (load, other jobs, GPU), stated beside the machine this
    builder runs on. ``keep_runs``: also archive each sweep's light run files into
    ``out_dir/runs/<sweep name>/`` (:func:`keep_sweeps`), from which the folder can be rebuilt.
    """
    sweeps = [Path(d) for d in (sweep_dir if isinstance(sweep_dir, list) else [sweep_dir])]
    out_dir = Path(out_dir)
    write_report(sweeps, out_dir, order=order, compare=compare, late=late, at=at)
    kept = keep_sweeps(sweeps, out_dir / RUNS_DIR) if keep_runs else []
    summary = combined_summary(sweeps)
    table = (out_dir / "table.md").read_text()
    for sweep in sweeps:
        table = table.replace(str(sweep.resolve()), "<sweep dir>")
    if len(sweeps) > 1:
        table = table.replace(os.path.commonpath([str(d.resolve()) for d in sweeps]),
                              "<sweep dirs>")
    (out_dir / "table.md").write_text(table)
    status = ", ".join(f"{n} {s}" for s, n in sorted(summary["statuses"].items()))
    dirs = "<sweep dir>" if len(sweeps) == 1 else " ".join(f"<sweep {i}>" for i in
                                                            range(1, len(sweeps) + 1))
    span = ("first job start to last metrics.json" if len(sweeps) == 1 else
            f"summed over the {len(sweeps)} sweeps, each first job start to last metrics.json")
    text = [
        f"# Reference: `{out_dir.name}`", "",
        "Produced from the repository root with:", "", "```bash",
        command or "\n".join(_recorded_command(sweep) for sweep in sweeps),
        f"semdp-report {dirs}   # or: python -m semdp.experiments.reference {dirs} "
        f"{out_dir.as_posix()}", "```", "",
        f"- Runs: {summary['runs']} ({status}); finished {summary['finished']}.",
        f"- Sweep wall time: {summary['sweep_wall_s'] / 60:.1f} min ({span}); "
        "summed training wall time of the runs: "
        f"{summary['run_wall_s'] / 60:.1f} min (final evaluations and post-training hooks "
        "are in the sweep time only).",
        f"- Machine (where this folder was built): {this_machine()}."
        + (f" {machine}" if machine else ""),
    ]
    if kept:
        text.append(f"- Kept runs: `{RUNS_DIR}/` holds each run's metrics.json, progress.csv, "
                    "config.yaml and trained policy (policy.pt; no checkpoints), one folder "
                    "per sweep ("
                    + ", ".join(f"`{name}`" for name in kept) + "); rebuild or extend this "
                    "folder with `python -m semdp.experiments.reference "
                    f"{out_dir.as_posix()}/{RUNS_DIR}/* [more sweeps] {out_dir.as_posix()} "
                    "--keep-runs` and this file's options.")
    if note:
        text += ["", note]
    text += ["", "## Table", "", table.replace("# Results", "### Results", 1)]
    path = out_dir / "COMMAND.md"
    path.write_text("\n".join(text))
    return path


def main(argv: list[str] | None = None) -> None:
    """CLI entry point."""
    parser = argparse.ArgumentParser(prog="python -m semdp.experiments.reference",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep_dir", type=Path, nargs="+",
                        help="one sweep directory, or several reported together")
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--order", default="", help="comma-separated method labels first")
    parser.add_argument("--note", default="", help="a paragraph added to COMMAND.md")
    parser.add_argument("--machine", default="",
                        help="how the runs ran: threads, jobs at a time, load, other jobs")
    parser.add_argument("--command", default="",
                        help="the command(s) to record (default: from multirun.yaml)")
    parser.add_argument("--compare", default="",
                        help="two method labels A,B: add the differences A - B")
    parser.add_argument("--late", type=float, default=0.0,
                        help="also tabulate the training episodes over this last fraction")
    parser.add_argument("--at", default="",
                        help="env-step marks: the training-episode table of runs stopped there")
    parser.add_argument("--keep-runs", action="store_true",
                        help="archive the runs' light files into <out_dir>/runs/ (rebuildable)")
    args = parser.parse_args(argv)
    order = [s.strip() for s in args.order.split(",") if s.strip()]
    path = write_reference(list(args.sweep_dir), args.out_dir, order, args.note, args.command,
                           parse_compare(args.compare), args.late, parse_marks(args.at),
                           args.machine, args.keep_runs)
    print(path.read_text())


if __name__ == "__main__":
    main()
