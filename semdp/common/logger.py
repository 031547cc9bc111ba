"""Run-directory writers: ``progress.csv`` (one row per epoch) and ``metrics.json`` (SPEC §4.3).

The header follows the run-directory contract of the project; algorithm-specific columns are
appended after the common ones. An empty cell means "not measured this epoch".
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

COMMON_COLUMNS: tuple[str, ...] = (
    "epoch", "env_steps", "wall_time_s", "fps", "ep_return", "ep_cost", "ep_length",
    "lagrange_multiplier", "cost_threshold", "eval_return", "eval_cost",
)
#: Columns that depend on the machine's speed; everything else is a function of the seed.
TIMING_COLUMNS: tuple[str, ...] = ("wall_time_s", "fps")


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


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
        self.columns = list(COMMON_COLUMNS) + [c for c in extra_columns if c not in COMMON_COLUMNS]
        kept: list[list[str]] = []
        if keep_epochs is not None and self.path.exists():
            with self.path.open(newline="") as f:
                rows = list(csv.reader(f))
            if rows and rows[0] == self.columns:
                kept = [r for r in rows[1:] if r and int(r[0]) <= keep_epochs]
        with self.path.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(self.columns)
            writer.writerows(kept)

    def write(self, row: Mapping[str, Any]) -> None:
        """Append one epoch; unknown keys are an error, missing keys are empty cells."""
        unknown = set(row) - set(self.columns)
        if unknown:
            raise KeyError(f"columns {sorted(unknown)} not in the header {self.columns}")
        with self.path.open("a", newline="") as f:
            csv.writer(f).writerow([_cell(row.get(c)) for c in self.columns])


def write_metrics(path: Path, metrics: Mapping[str, Any]) -> None:
    """Write ``metrics.json`` atomically (write to a temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(metrics, indent=2, default=float) + "\n")
    tmp.replace(path)
