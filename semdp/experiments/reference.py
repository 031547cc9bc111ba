"""Turn a finished sweep into a committed reference folder (outputs/reference/README.md).

    python -m semdp.experiments.reference <sweep dir> outputs/reference/<preset> [--order ...]
    python -m semdp.experiments.reference <sweep s0> <sweep s1> outputs/reference/<preset>

Writes the ``semdp-report`` table and figures into the folder (no checkpoints or run
directories) and ``COMMAND.md``: the exact command (from the sweep's ``multirun.yaml``), the
sweep's wall time (first job start to last ``metrics.json``), the summed per-run training wall
time, the number of runs and their status, the machine, and the table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import time
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from semdp.report import parse_compare, parse_marks, write_report


def this_machine() -> str:
    """The machine the reference is built on: cores, architecture and Python."""
    return (f"{os.cpu_count()} logical CPUs ({platform.machine()}), "
            f"{platform.python_implementation()} {platform.python_version()}")


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
    """Run count, statuses, summed run wall time and the sweep's wall time (seconds)."""
    metrics_files = sorted(sweep_dir.rglob("metrics.json"))
    metrics_files = [p for p in metrics_files if "report" not in p.parts]
    statuses: dict[str, int] = {}
    run_wall = 0.0
    for path in metrics_files:
        metrics = json.loads(path.read_text())
        statuses[metrics.get("status", "?")] = statuses.get(metrics.get("status", "?"), 0) + 1
        run_wall += float(metrics.get("wall_time_s") or 0.0)
    end = max((p.stat().st_mtime for p in metrics_files), default=time.time())
    multirun = sweep_dir / "multirun.yaml"
    # Without multirun.yaml (runs collected from several sweeps) the summed run time stands in.
    sweep_wall = end - multirun.stat().st_mtime if multirun.is_file() else run_wall
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


def write_reference(sweep_dir: Path | list[Path], out_dir: Path,
                    order: list[str] | None = None, note: str = "", command: str = "",
                    compare: tuple[str, str] | None = None, late: float = 0.0,
                    at: tuple[float, ...] = (), machine: str = "") -> Path:
    """Report + ``COMMAND.md`` into ``out_dir``; returns the ``COMMAND.md`` path.

    ``sweep_dir``: one sweep, or several reported together (their commands, from each
    ``multirun.yaml``, one per line; their run counts and wall times added). ``machine``: how
    the runs shared the machine (load, other jobs, GPU), stated beside the machine this
    builder runs on.
    """
    sweeps = [Path(d) for d in (sweep_dir if isinstance(sweep_dir, list) else [sweep_dir])]
    out_dir = Path(out_dir)
    write_report(sweeps, out_dir, order=order, compare=compare, late=late, at=at)
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
    args = parser.parse_args(argv)
    order = [s.strip() for s in args.order.split(",") if s.strip()]
    path = write_reference(list(args.sweep_dir), args.out_dir, order, args.note, args.command,
                           parse_compare(args.compare), args.late, parse_marks(args.at),
                           args.machine)
    print(path.read_text())


if __name__ == "__main__":
    main()
