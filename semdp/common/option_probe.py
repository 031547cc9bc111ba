"""Pick the faster of two ways of doing the same work from their measured times.

The on-policy algorithms' helper processes (semdp/README.md, "Throughput") pay off only when a
core is free: on a machine other jobs keep busy the helper and the trainer take turns on one
core and add their pipe traffic. Both ways give the same numbers, so the choice may change
between epochs; :class:`FasterOption` measures each once, keeps the faster, leaves it when it
gets slower than the other was (the load changed) and measures the other again every
``reprobe_every`` epochs.
"""

from __future__ import annotations


class FasterOption:
    """Which of ``False`` (without the helper) and ``True`` (with it) to use next.

    Each option's latest time is kept; the faster is used, so the one in use is left as soon as
    it takes longer than the other last did, and the other is measured again every
    ``reprobe_every`` epochs (its time may have improved since).

    Args:
        allowed: ``False`` pins the choice to ``False``.
        reprobe_every: epochs after which the option not in use is measured again.
    """

    def __init__(self, allowed: bool = True, reprobe_every: int = 25) -> None:
        self.allowed = allowed
        self.reprobe_every = reprobe_every
        self.last: dict[bool, float | None] = {False: None, True: None}
        self._since_probe = 0
        self._current = False

    def choose(self) -> bool:
        """The option for the next measurement."""
        if not self.allowed or self.last[False] is None:
            self._current = False
        elif self.last[True] is None:
            self._current = True
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

    def disallow(self) -> None:
        """Pin the choice to ``False`` from now on."""
        self.allowed = False
