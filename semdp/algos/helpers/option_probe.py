"""Pick the faster of two ways of doing the same work from their measured times.

The on-policy algorithms' helper processes (docs/performance.md) pay off only when a
core is free: on a machine other jobs keep busy the helper and the trainer take turns on one
core and add their pipe traffic. Both ways give the same numbers, so the choice may change
between epochs; :class:`FasterOption` measures each once, keeps the faster, leaves it when it
gets slower than the other was (the load changed) and measures the other again every
``reprobe_every`` epochs. Where a core is seen idle at the start (:func:`idle_core`), it starts
with the helper and measures the way without it only if the helper's way slows down: on a quiet
machine no epoch is spent on the slower way.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

#: The helper's way is measured alone until it takes this much longer than its best epoch.
SLOWDOWN = 1.3


def _cpu_times() -> tuple[float, float] | None:
    """(idle, total) jiffies of all CPUs from ``/proc/stat`` (None where there is none)."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    except OSError:
        return None
    values = [float(v) for v in fields]
    return values[3] + (values[4] if len(values) > 4 else 0.0), sum(values)


def idle_core(sample_s: float = 0.1, cpus: int | None = None) -> bool:
    """Whether another core than this process's is idle: over ``sample_s`` seconds (this
    process sleeping) at least 1.8 CPUs' worth of idle time. False where it cannot be read."""
    cpus = cpus or os.cpu_count() or 1
    if cpus < 2:
        return False
    before = _cpu_times()
    time.sleep(sample_s)
    after = _cpu_times()
    if before is None or after is None or after[1] <= before[1]:
        return False
    idle_share = (after[0] - before[0]) / (after[1] - before[1])
    return idle_share * cpus >= 1.8


class FasterOption:
    """Which of ``False`` (without the helper) and ``True`` (with it) to use next.

    Each option's latest time is kept; the faster is used, so the one in use is left as soon as
    it takes longer than the other last did, and the other is measured again every
    ``reprobe_every`` epochs (its time may have improved since).

    With ``first=True`` it starts with ``True`` and measures ``False`` only once ``True`` takes
    :data:`SLOWDOWN` times its best time (the machine got busy); then as above.

    Args:
        allowed: ``False`` pins the choice to ``False``.
        reprobe_every: epochs after which the option not in use is measured again.
        first: the option measured first.
    """

    def __init__(self, allowed: bool = True, reprobe_every: int = 25,
                 first: bool = False) -> None:
        self.allowed = allowed
        self.reprobe_every = reprobe_every
        self.first = bool(first) and allowed
        self.last: dict[bool, float | None] = {False: None, True: None}
        self.best: dict[bool, float | None] = {False: None, True: None}
        self._since_probe = 0
        self._current = False

    def choose(self) -> bool:
        """The option for the next measurement."""
        if not self.allowed:
            self._current = False
        elif self.last[self.first] is None:
            self._current = self.first
        elif self.last[not self.first] is None:
            last, best = self.last[True], self.best[True]
            stay = self.first and last is not None and best is not None and \
                last <= SLOWDOWN * best
            self._current = True if stay else not self.first
        else:
            faster = self.last[True] <= self.last[False]  # type: ignore[operator]
            if self._current != faster:
                self._current = faster
            elif self._since_probe >= self.reprobe_every:
                self._current = not faster
                self._since_probe = 0
        self._since_probe += 1
        return self._current

    def record(self, option: bool, seconds: float) -> None:
        """The time one measurement with ``option`` took."""
        self.last[option] = seconds
        best = self.best[option]
        self.best[option] = seconds if best is None else min(best, seconds)

    def disallow(self) -> None:
        """Pin the choice to ``False`` from now on."""
        self.allowed = False
