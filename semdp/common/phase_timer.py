"""The seconds per phase of an algorithm's epoch (the ``time_*`` and ``fps`` columns of
``progress.csv``; docs/training.md, "Run directory"): ``simulation`` stepping the envs or waiting
for the process that steps them, ``policy`` forward passes while acting, ``storage`` buffer
writes, bookkeeping and GAE, ``update`` optimisation; ``simulation_worker`` the helper's
stepping, which overlaps them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

PHASES: tuple[str, ...] = ("simulation", "policy", "storage", "update", "simulation_worker")


class PhaseTimer:
    """Accumulated seconds per phase; :attr:`seconds` is a plain dict of floats."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(PHASES, 0.0)

    def add(self, phase: str, seconds: float) -> None:
        """Book ``seconds`` to ``phase``."""
        self.seconds[phase] += seconds

    @contextmanager
    def phase(self, name: str) -> Iterator[None]:
        """Book the time spent inside the ``with`` block to ``name``."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - start

    def snapshot(self) -> dict[str, float]:
        """A copy of the current totals (subtract two snapshots for an interval)."""
        return dict(self.seconds)
