"""The self-paced threshold curriculum (thesis Alg. 1, Eqs. 2.8-2.10, 2.12).

One implementation for both users: the toy problem's dynamics
(:mod:`solvers.self_paced_lagrangian`, Fig. 2.1) and SP-PPO-Lag's cost limit
(``semdp.algos.sp_ppo_lag``).

The thresholds are ``D = {base^(N - i) | i = 0..M}`` (Eq. 2.12, base 2 in the thesis) restricted
to values above the target, loosest first, followed by the target itself. Two readings of how
the current threshold ``d_i`` is chosen (:data:`THRESHOLD_RULES`):

* ``"tighten"`` (§2.4.1): start at the loosest threshold and move one step tighter whenever
  the current stage is done; never loosen. What "done" means is the caller's: the toy requires
  the stage's KKT conditions, SP-PPO-Lag an episode cost below ``d_i``.
* ``"literal"`` (Eq. 2.9 / Alg. 1 as written): ``d_i = max{d in D : d <= cost}``, re-chosen at
  every multiplier update (it loosens again when the cost rises); the target when the cost is
  below every threshold.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

#: Readings of the threshold rule (see the module docstring).
THRESHOLD_RULES: tuple[str, ...] = ("tighten", "literal")


def threshold_schedule(
    initial_exponent: int, num_thresholds: int, target: float = 0.0, base: float = 2.0
) -> tuple[float, ...]:
    """Thresholds of Eq. 2.12 above ``target``, loosest first, followed by ``target``.

    Args:
        initial_exponent: N in ``d_i = base^(N - i)``.
        num_thresholds: M, the last index (so at most M + 1 thresholds precede the target).
        target: the final limit (0 in the toy problem, the run's cost limit in SP-PPO-Lag).
        base: base of the geometric schedule (> 1).

    Returns:
        ``(base^N, ..., base^(N-M), target)`` without the entries at or below ``target``.

    Raises:
        ValueError: if N is not an integer, M is not an integer >= 0, ``target`` is not a
            finite number >= 0 or ``base`` is not a finite number > 1.
    """
    if isinstance(initial_exponent, bool) or not isinstance(initial_exponent, numbers.Integral):
        raise ValueError(f"initial_exponent must be an integer, got {initial_exponent!r}")
    if (
        isinstance(num_thresholds, bool)
        or not isinstance(num_thresholds, numbers.Integral)
        or num_thresholds < 0
    ):
        raise ValueError(f"num_thresholds must be an integer >= 0, got {num_thresholds!r}")
    if not (isinstance(target, numbers.Real) and math.isfinite(target) and target >= 0):
        raise ValueError(f"target must be a finite number >= 0, got {target!r}")
    if not (isinstance(base, numbers.Real) and math.isfinite(base) and base > 1):
        raise ValueError(f"base must be a finite number > 1, got {base!r}")
    loose = (base ** (int(initial_exponent) - i) for i in range(int(num_thresholds) + 1))
    return (*(d for d in loose if d > target), float(target))


def literal_threshold_index(cost: float, schedule: Sequence[float]) -> int:
    """Eq. 2.9 read literally: index of the largest threshold not above ``cost``.

    ``schedule`` is sorted loosest first and ends with the target; when ``cost`` is below every
    threshold (a strictly feasible point) the target (last index) is returned.
    """
    for index, threshold in enumerate(schedule):
        if threshold <= cost:
            return index
    return len(schedule) - 1


class ThresholdSchedule:
    """Position in a threshold curriculum under one of :data:`THRESHOLD_RULES`.

    Args:
        thresholds: strictly decreasing thresholds ending with the target (e.g.
            :func:`threshold_schedule`).
        rule: ``"tighten"`` or ``"literal"``.
        index: the starting position (the loosest threshold by default).

    Raises:
        ValueError: for an unknown rule, an empty schedule or an index outside it.
    """

    def __init__(self, thresholds: Sequence[float], rule: str = "tighten", index: int = 0) -> None:
        if rule not in THRESHOLD_RULES:
            raise ValueError(f"rule must be one of {list(THRESHOLD_RULES)}, got {rule!r}")
        if len(thresholds) == 0:
            raise ValueError("thresholds must hold at least the target")
        if not 0 <= index < len(thresholds):
            raise ValueError(f"index must be in [0, {len(thresholds) - 1}], got {index}")
        self.rule = rule
        #: Thresholds from loosest to the target.
        self.thresholds: list[float] = [float(d) for d in thresholds]
        self.index = int(index)

    @property
    def current(self) -> float:
        """The threshold in force now."""
        return self.thresholds[self.index]

    def select(self, cost: float, stage_done: bool) -> float:
        """Choose the threshold for the next multiplier update and return it.

        Args:
            cost: the current constraint value (``literal``: d_i is chosen from it).
            stage_done: whether the current stage is done (``tighten``: move one step
                tighter, unless already at the target).
        """
        if self.rule == "literal":
            self.index = literal_threshold_index(cost, self.thresholds)
        elif stage_done and self.index < len(self.thresholds) - 1:
            self.index += 1
        return self.current

    def state_dict(self) -> dict[str, Any]:
        """Position in the schedule (and the schedule, to check it on loading)."""
        return {"index": self.index, "thresholds": list(self.thresholds)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`; the saved schedule must equal this one."""
        if list(state["thresholds"]) != self.thresholds:
            raise ValueError(
                f"checkpoint thresholds {state['thresholds']} differ from {self.thresholds}"
            )
        self.index = int(state["index"])
