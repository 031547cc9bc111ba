"""Self-paced cost-threshold schedule of the SP-PPO-Lagrangian (thesis Alg. 1, Eqs. 2.8-2.10, 2.12).

The threshold set is ``D = {base^(N - i) | i = 0..M}`` (Eq. 2.12) restricted to values above the
target limit, followed by the target itself. The thesis gives two readings of how the current
threshold ``d_i`` is chosen from the estimated cost ``J_c``:

* ``"literal"`` -- Eq. 2.9 / Alg. 1 as written: ``d_i = max{d in D : d <= J_c}``, re-chosen every
  epoch (it can loosen again when the cost rises); the target is used when ``J_c`` is below
  every element.
* ``"tighten"`` -- §2.4.1's prose: start at the loosest threshold and move to the next tighter
  one whenever the current one is satisfied (``J_c < d_i``); never loosen.

With ``"literal"`` the violation ``J_c - d_i`` is never negative while ``J_c`` is above the
target, so lambda can only grow; with ``"tighten"`` lambda relaxes while the policy is inside a
loose threshold, which is the curriculum §2.4.1 describes. ``"tighten"`` is the default here.
"""

from __future__ import annotations

import math
from typing import Any

RULES = ("tighten", "literal")


class SelfPacedThresholds:
    """Threshold curriculum from loose to the target limit.

    Args:
        target: the final cost limit d (the run's ``cost_limit``).
        initial_exponent: N in Eq. 2.12 (loosest threshold ``base**N``).
        num_thresholds: M in Eq. 2.12 (thresholds ``base**N .. base**(N-M)``).
        rule: ``"tighten"`` or ``"literal"`` (see the module docstring).
        base: base of the geometric schedule (2 in the thesis).
    """

    def __init__(
        self,
        target: float,
        initial_exponent: int = 8,
        num_thresholds: int = 3,
        rule: str = "tighten",
        base: float = 2.0,
    ) -> None:
        if not math.isfinite(target) or target < 0:
            raise ValueError(f"target must be a finite number >= 0, got {target}")
        if num_thresholds < 0:
            raise ValueError(f"num_thresholds must be >= 0, got {num_thresholds}")
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
        if base <= 1:
            raise ValueError(f"base must be > 1, got {base}")
        self.target = float(target)
        self.rule = rule
        loose = [base ** (initial_exponent - i) for i in range(num_thresholds + 1)]
        #: Thresholds from loosest to the target (strictly decreasing).
        self.thresholds: list[float] = [d for d in loose if d > self.target] + [self.target]
        self._index = 0

    @property
    def current(self) -> float:
        """The threshold in force now."""
        return self.thresholds[self._index]

    def update(self, estimated_cost: float) -> float:
        """Choose the threshold for this epoch's multiplier update from ``J_c``; return it."""
        if self.rule == "literal":
            below = [i for i, d in enumerate(self.thresholds) if d <= estimated_cost]
            self._index = below[0] if below else len(self.thresholds) - 1
        elif estimated_cost < self.current and self._index < len(self.thresholds) - 1:
            self._index += 1
        return self.current

    def state_dict(self) -> dict[str, Any]:
        """Position in the schedule."""
        return {"index": self._index, "thresholds": list(self.thresholds)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        if list(state["thresholds"]) != self.thresholds:
            raise ValueError(
                f"checkpoint thresholds {state['thresholds']} differ from {self.thresholds}"
            )
        self._index = int(state["index"])
