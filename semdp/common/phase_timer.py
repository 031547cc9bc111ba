"""Where an algorithm's wall time goes: seconds per phase, for ``semdp-bench train``.

The on-policy algorithms (semdp/README.md, "Throughput") book every rollout step and update
into four phases: ``simulation`` (stepping the environments, or waiting for the process that
steps them), ``policy`` (forward passes of actor and critics while acting), ``storage``
(rollout buffer writes, episode bookkeeping, normaliser update, GAE) and ``update`` (actor and
critic optimisation). ``simulation_worker`` is the time the helper process spent stepping
(``vectorization="async"``), which overlaps the other phases.
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
