"""Pick the faster of two ways of doing the same work from their measured times.

The on-policy algorithms' helper processes (semdp/README.md, "Throughput") pay off only when a
core is free: on a machine other jobs keep busy the helper and the trainer take turns on one
core and add their pipe traffic. Both ways give the same numbers, so the choice may change
between epochs; :class:`FasterOption` measures each once, keeps the faster, and measures the
other again when the kept one slows down (the load changed) or every ``reprobe_every`` epochs.
"""

from __future__ import annotations

import math


class FasterOption:
    """Which of ``False`` (without the helper) and ``True`` (with it) to use next.

    Args:
        allowed: ``False`` pins the choice to ``False``.
        reprobe_every: epochs after which the option not in use is measured again.
        slowdown: the option in use is re-compared when its time exceeds its best this much.
    """

    def __init__(self, allowed: bool = True, reprobe_every: int = 25,
                 slowdown: float = 1.3) -> None:
        self.allowed = allowed
        self.reprobe_every, self.slowdown = reprobe_every, slowdown
        self.last: dict[bool, float | None] = {False: None, True: None}
        self.best: dict[bool, float] = {False: math.inf, True: math.inf}
        self._since_probe = 0
        self._current = False

    def choose(self) -> bool:
        """The option for the next measurement."""
        if not self.allowed:
            self._current = False
        elif self.last[False] is None:
            self._current = False
        elif self.last[True] is None:
            self._current = True
        else:
            faster = self.last[True] <= self.last[False]  # type: ignore[operator]
            slowed = self.last[faster] > self.slowdown * self.best[faster]  # type: ignore[operator]
            if self._current != faster:  # a probe just ran: go back to (or stay with) the faster
                self._current = faster
            elif slowed or self._since_probe >= self.reprobe_every:
                self._current = not faster
                self._since_probe = 0
                self.best[faster] = self.last[faster]  # type: ignore[assignment]
        self._since_probe += 1
        return self._current

    def record(self, option: bool, seconds: float) -> None:
        """The time one measurement with ``option`` took."""
        self.last[option] = seconds
        self.best[option] = min(self.best[option], seconds)

    def disallow(self) -> None:
        """Pin the choice to ``False`` from now on."""
        self.allowed = False
