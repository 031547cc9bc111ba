"""TensorBoard event files beside ``progress.csv`` (optional extra ``tensorboard``).

:class:`TensorBoardRows` is a :class:`semdp.common.logger.RowSink`: every numeric cell of a
``progress.csv`` row becomes a scalar under the column's name, at step ``env_steps`` (the
row's environment steps; high-level steps for a Safety-Embedded MDP run, as in its CSV).
Empty cells (``None``/NaN) are skipped. ``torch.utils.tensorboard.SummaryWriter`` needs the
``tensorboard`` package, so this module imports it only when a sink is made.

    tensorboard --logdir outputs/
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

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
