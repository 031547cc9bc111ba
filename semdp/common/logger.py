"""Run-directory writers: ``progress.csv`` (one row per epoch) and ``metrics.json``.

The header follows the run-directory contract of the project (docs/training.md, "Run
directory"); algorithm-specific columns are appended after the common ones. An empty cell
means "not measured this epoch".

What else happens to a row is decided by whoever starts the run, not by the epoch loop: inside
:func:`run_logging`, every :class:`ProgressCSV` opened adds the columns of the given
:class:`RowSource` objects (e.g. the SEMDP time split) to its header and each row, and hands
every written row to the given :class:`RowSink` objects (e.g. TensorBoard event files), which
are closed when the context ends.

One more piece of what a run writes lives here: :class:`TensorBoardRows`, a :class:`RowSink`
that mirrors every numeric cell of a row into TensorBoard event files beside ``progress.csv``
(optional extra ``tensorboard``; scalars at step ``env_steps``, empty cells skipped; view with
``tensorboard --logdir outputs/``), and :class:`PhaseTimer`, the seconds per phase of an
algorithm's epoch (``simulation`` stepping the envs or waiting for the process that steps them,
``policy`` forward passes while acting, ``storage`` buffer writes, bookkeeping and GAE,
``update`` optimisation; ``simulation_worker`` the helper's stepping, which overlaps them).
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import importlib.util
import json
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

COMMON_COLUMNS: tuple[str, ...] = (
    "epoch", "env_steps", "wall_time_s", "fps", "ep_return", "ep_cost", "ep_length",
    "lagrange_multiplier", "cost_threshold", "eval_return", "eval_cost",
)
#: Per-epoch seconds of the Safety-Embedded MDP time split (docs/semdp.md, "The wrapper, the
#: planner and the certificate"), added by :class:`semdp.embedded.timing.EpochTimeSplit` to
#: SEMDP runs.
TIME_SPLIT_COLUMNS: tuple[str, ...] = (
    "time_perception_s", "time_plan_s", "time_follow_s", "time_sim_s",
    "time_learning_and_overhead_s",
)
#: Columns that depend on the machine's speed; everything else is a function of the seed.
TIMING_COLUMNS: tuple[str, ...] = ("wall_time_s", "fps", *TIME_SPLIT_COLUMNS)


class RowSource(Protocol):
    """Extra ``progress.csv`` columns computed outside the algorithm."""

    columns: tuple[str, ...]

    def start(self) -> None:
        """Called when the CSV is opened (after a resumed run loaded its checkpoint)."""

    def values(self, row: Mapping[str, Any]) -> Mapping[str, Any]:
        """This epoch's values of :attr:`columns`, given the algorithm's row."""


class RowSink(Protocol):
    """Receives every row written to ``progress.csv`` (all columns, ``None`` = empty cell)."""

    def write(self, row: Mapping[str, Any]) -> None:
        """Record one epoch."""

    def close(self) -> None:
        """Flush and release files."""


#: ``factory(run_dir, purge_step)`` -> sink; ``purge_step`` is the first step after the rows a
#: resumed CSV kept (later steps of the earlier session are to be discarded), else ``None``.
SinkFactory = Callable[[Path, int | None], RowSink]


@dataclass
class RunLogging:
    """Sources and sink factories applied to the CSVs opened inside :func:`run_logging`."""

    sources: Sequence[RowSource] = ()
    sink_factories: Sequence[SinkFactory] = ()
    opened: list[RowSink] = field(default_factory=list)


_ACTIVE: contextvars.ContextVar[RunLogging | None] = contextvars.ContextVar(
    "semdp_run_logging", default=None
)


@contextlib.contextmanager
def run_logging(
    sources: Sequence[RowSource] = (), sink_factories: Sequence[SinkFactory] = ()
) -> Iterator[RunLogging]:
    """Apply ``sources`` and ``sink_factories`` to every :class:`ProgressCSV` opened inside;
    close the sinks on exit (also on an exception)."""
    active = RunLogging(tuple(sources), tuple(sink_factories))
    token = _ACTIVE.set(active)
    try:
        yield active
    finally:
        _ACTIVE.reset(token)
        for sink in active.opened:
            sink.close()


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def _read_kept(path: Path, columns: list[str], keep_epochs: int) -> list[list[str]]:
    """Rows with ``epoch <= keep_epochs`` of an existing CSV, re-ordered to ``columns``.

    A header with columns missing from ``columns`` (a different algorithm) keeps nothing; one
    with fewer columns (a run started before a column was added) keeps its rows, the new
    columns empty.
    """
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows or "epoch" not in rows[0] or not set(rows[0]) <= set(columns):
        return []
    header = rows[0]
    kept = []
    for r in rows[1:]:
        if not r:
            continue
        cells = dict(zip(header, r, strict=False))
        if int(cells["epoch"]) <= keep_epochs:
            kept.append([cells.get(c, "") for c in columns])
    return kept


class ProgressCSV:
    """Append-only per-epoch CSV.

    Args:
        path: file to write.
        extra_columns: algorithm-specific columns after :data:`COMMON_COLUMNS`.
        keep_epochs: when resuming, keep the existing rows with ``epoch <= keep_epochs`` and
            append after them; ``None`` starts a fresh file.
    """

    def __init__(
        self, path: Path, extra_columns: Sequence[str] = (), keep_epochs: int | None = None
    ) -> None:
        self.path = Path(path)
        active = _ACTIVE.get()
        self.sources: tuple[RowSource, ...] = tuple(active.sources) if active else ()
        self.columns = list(COMMON_COLUMNS)
        for column in [*extra_columns, *(c for s in self.sources for c in s.columns)]:
            if column not in self.columns:
                self.columns.append(column)
        kept: list[list[str]] = []
        if keep_epochs is not None and self.path.exists():
            kept = _read_kept(self.path, self.columns, keep_epochs)
        with self.path.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(self.columns)
            writer.writerows(kept)
        for source in self.sources:
            source.start()
        self.sinks: list[RowSink] = []
        if active:
            purge_step = None
            if keep_epochs is not None:
                at = self.columns.index("env_steps")
                steps = [int(float(r[at])) for r in kept if r[at] != ""]
                purge_step = max(steps, default=0) + 1
            for factory in active.sink_factories:
                sink = factory(self.path.parent, purge_step)
                self.sinks.append(sink)
                active.opened.append(sink)

    def write(self, row: Mapping[str, Any]) -> None:
        """Append one epoch; unknown keys are an error, missing keys are empty cells."""
        unknown = set(row) - set(self.columns)
        if unknown:
            raise KeyError(f"columns {sorted(unknown)} not in the header {self.columns}")
        full = dict(row)
        for source in self.sources:
            full.update(source.values(row))
        with self.path.open("a", newline="") as f:
            csv.writer(f).writerow([_cell(full.get(c)) for c in self.columns])
        complete = {c: full.get(c) for c in self.columns}
        for sink in self.sinks:
            sink.write(complete)


def write_metrics(path: Path, metrics: Mapping[str, Any]) -> None:
    """Write ``metrics.json`` atomically (write to a temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(metrics, indent=2, default=float) + "\n")
    tmp.replace(path)


# ----------------------------------------------------------------- TensorBoard
#: The x axis of every scalar.
STEP_COLUMN = "env_steps"


def tensorboard_available() -> bool:
    """Whether the ``tensorboard`` package (needed by ``SummaryWriter``) is importable."""
    return importlib.util.find_spec("tensorboard") is not None


def _scalar(value: Any) -> float | None:
    if value is None or isinstance(value, bool | str):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


class TensorBoardRows:
    """Writes each row as scalars into ``run_dir`` (``events.out.tfevents.*`` files).

    Args:
        run_dir: directory of the event files (the run directory).
        purge_step: on a resume, the first step written again; TensorBoard discards the
            earlier session's events from that step on (``SummaryWriter(purge_step=...)``).
    """

    def __init__(self, run_dir: Path, purge_step: int | None = None) -> None:
        from torch.utils.tensorboard import SummaryWriter

        self.purge_step = purge_step
        self.writer = SummaryWriter(log_dir=str(run_dir), purge_step=purge_step)

    def write(self, row: Mapping[str, Any]) -> None:
        """Add every numeric column of ``row`` at step ``row["env_steps"]`` and flush."""
        step = _scalar(row.get(STEP_COLUMN))
        if step is None:
            return
        for column, value in row.items():
            number = _scalar(value)
            if number is not None:
                self.writer.add_scalar(column, number, global_step=int(step))
        self.writer.flush()

    def close(self) -> None:
        """Flush and close the event file."""
        self.writer.close()


# ----------------------------------------------------------------- phase timer
