"""What ``semdp-train`` adds to a run's ``progress.csv`` logging (docs/training.md, "Run
directory"): the per-epoch SEMDP time split for Safety-Embedded MDP runs and, with
``tensorboard: true`` (``conf/train.yaml``) and the ``tensorboard`` package installed, event
files in the run directory holding every ``progress.csv`` scalar.
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator
from typing import Any

from omegaconf import DictConfig

from semdp.common.logger import (
    RowSource,
    RunLogging,
    SinkFactory,
    TensorBoardRows,
    run_logging,
    tensorboard_available,
)

logger = logging.getLogger(__name__)


def tensorboard_enabled(cfg: DictConfig) -> bool:
    """``cfg.tensorboard`` (default true) and the package importable; says once why not."""
    if not bool(cfg.get("tensorboard", True)):
        return False
    if not tensorboard_available():
        logger.info("tensorboard: true, but the tensorboard package is not installed "
                    "(pip install -e '.[tensorboard]'); writing progress.csv only")
        return False
    return True


def _semdp_sources(algo: Any) -> list[RowSource]:
    """The SEMDP time split, for runs with a Safety-Embedded MDP env (its modules, which
    import the planner and CasADi, are loaded only then)."""
    if "semdp.embedded.wrapper" not in sys.modules:  # no SEMDP env was built
        return []
    from semdp.embedded.timing import EpochTimeSplit, has_semdp_env

    return [EpochTimeSplit(algo)] if has_semdp_env(algo) else []


@contextlib.contextmanager
def progress_logging(cfg: DictConfig, algo: Any) -> Iterator[RunLogging]:
    """Context for :meth:`Algorithm.learn`: the row sources and sinks of this run."""
    sources = _semdp_sources(algo)
    sinks: list[SinkFactory] = [TensorBoardRows] if tensorboard_enabled(cfg) else []
    with run_logging(sources, sinks) as active:
        yield active
