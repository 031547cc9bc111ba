"""``semdp-bench ab [base=REF] [new=REF] [n=N] -- COMMAND...``: time one command on two versions
of the code, alternately, and print each side's times, medians and their ratio.

The base side is a ``git worktree`` of ``base`` (default ``HEAD``) made in a temporary folder
(or the folder given as ``base_dir=``); the new side is the working tree (or a worktree of
``new``). Each of ``n`` rounds (default 5) runs the command once on the base and once on the
new side, in that order, so both see the same load. A side runs with ``PYTHONPATH`` at its
folder and the folder as working directory; before timing, the tool checks that ``import
semdp`` there loads that side's code (an editable install whose import hook wins over
``PYTHONPATH`` would time the same code twice: reinstall with ``pip install -e .
--config-settings editable_mode=compat``). A failing run stops the comparison with its output.

    semdp-bench ab base=HEAD~1 n=5 -- semdp-bench semdp steps=2000
    semdp-bench ab base=main -- semdp-train algo=ppo_lag env=point_goal1 total_steps=100000

Prints one row per side (every time, the median) and ``base / new`` of the medians (above 1:
the new side is faster). Docs: docs/performance.md, "How to measure".
"""

from __future__ import annotations

import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from semdp.benchmarks.arguments import BenchArgumentError, as_int, parse_args

DEFAULTS = {"base": "HEAD", "new": "", "n": "5", "base_dir": ""}


@dataclass(frozen=True)
class Side:
    """One version of the code: its name and folder."""

    name: str
    folder: Path


def split_command(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """``key=value`` items before ``--`` and the command after it."""
    if "--" not in argv:
        raise BenchArgumentError("semdp-bench ab: give the command to time after '--', e.g. "
                                 "semdp-bench ab base=HEAD~1 -- semdp-bench semdp steps=2000")
    cut = list(argv).index("--")
    command = list(argv[cut + 1:])
    if not command:
        raise BenchArgumentError("semdp-bench ab: no command after '--'")
    return list(argv[:cut]), command


def repository_root() -> Path:
    found = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True,
                           text=True, check=False)
    if found.returncode != 0:
        raise SystemExit("semdp-bench ab: run it inside a git checkout of the project")
    return Path(found.stdout.strip())


def add_worktree(root: Path, ref: str, stack: ExitStack) -> Path:
    """A detached worktree of ``ref`` in a temporary folder, removed when ``stack`` closes."""
    folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ab_"))) / "tree"
    done = subprocess.run(["git", "worktree", "add", "--detach", str(folder), ref], cwd=root,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"semdp-bench ab: git worktree add {ref}: {done.stderr.strip()}")
    stack.callback(subprocess.run, ["git", "worktree", "remove", "--force", str(folder)],
                   cwd=root, capture_output=True, check=False)
    return folder


def side_environment(side: Side) -> dict[str, str]:
    path = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(side.folder), path) if p)}


def check_side(side: Side) -> None:
    """Stop unless ``import semdp`` in the side's environment loads the side's own code."""
    done = subprocess.run([sys.executable, "-c", "import semdp; print(semdp.__file__)"],
                          cwd=side.folder, env=side_environment(side), capture_output=True,
                          text=True, check=False)
    loaded = Path(done.stdout.strip() or ".").resolve()
    if done.returncode != 0 or side.folder.resolve() not in loaded.parents:
        raise SystemExit(
            f"semdp-bench ab: on the {side.name} side 'import semdp' loads "
            f"{done.stdout.strip() or done.stderr.strip()[-300:]}, not {side.folder}; an "
            "editable install's import hook wins over PYTHONPATH: reinstall with "
            "pip install -e . --config-settings editable_mode=compat")


def time_once(side: Side, command: list[str]) -> float:
    """Seconds the command takes on ``side``; stops with its output if it fails."""
    start = time.perf_counter()
    done = subprocess.run(command, cwd=side.folder, env=side_environment(side),
                          capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"semdp-bench ab: {shlex.join(command)} failed on the {side.name} "
                         f"side (exit {done.returncode}):\n{(done.stdout + done.stderr)[-2000:]}")
    return seconds


def compare(sides: tuple[Side, Side], command: list[str], rounds: int) -> dict[str, list[float]]:
    """``rounds`` alternating runs: base, new, base, new, ..."""
    times: dict[str, list[float]] = {side.name: [] for side in sides}
    for _ in range(rounds):
        for side in sides:
            times[side.name].append(time_once(side, command))
    return times


def report(times: dict[str, list[float]]) -> str:
    """The table: each side's times and median, then base / new."""
    medians = {name: statistics.median(values) for name, values in times.items()}
    lines = [f"{'side':<6} {'median s':>9}  times (s)"]
    for name, values in times.items():
        lines.append(f"{name:<6} {medians[name]:>9.3f}  " + " ".join(f"{v:.3f}" for v in values))
    ratio = medians["base"] / medians["new"]
    lines.append(f"base / new = {ratio:.3f} ({'new faster' if ratio > 1 else 'new not faster'})")
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    items, command = split_command(argv)
    args = parse_args("ab", items, DEFAULTS)
    rounds = as_int(args, "n", minimum=1)
    root = repository_root()
    with ExitStack() as stack:
        base = Path(args["base_dir"]) if args["base_dir"] else add_worktree(
            root, args["base"], stack)
        new = add_worktree(root, args["new"], stack) if args["new"] else root
        sides = (Side("base", base), Side("new", new))
        for side in sides:
            check_side(side)
        print(f"timing {shlex.join(command)}: {rounds} rounds, base "
              f"{args['base_dir'] or args['base']} ({base}), new "
              f"{args['new'] or 'the working tree'} ({new})", flush=True)
        print(report(compare(sides, command, rounds)))
