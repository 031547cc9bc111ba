"""SP-PPO-Lag's cost-threshold curriculum (thesis Alg. 1, Eqs. 2.8-2.10, 2.12).

The schedule and both threshold rules are :mod:`solvers.threshold_schedule`'s, shared with the
toy problem; this module only reads "stage done" as SP-PPO-Lag does: the estimated episode cost
``J_c`` is below the current threshold. With ``"literal"`` the violation ``J_c - d_i`` is never
negative while ``J_c`` is above the target, so lambda can only grow; with ``"tighten"`` (the
default) lambda relaxes while the policy is inside a loose threshold, which is the curriculum
§2.4.1 describes.
"""

from __future__ import annotations

from solvers.threshold_schedule import ThresholdSchedule, threshold_schedule


class SelfPacedThresholds(ThresholdSchedule):
    """Threshold curriculum from loose to the target limit.

    Args:
        target: the final cost limit d (the run's ``cost_limit``).
        initial_exponent: N in Eq. 2.12 (loosest threshold ``base**N``).
        num_thresholds: M in Eq. 2.12 (thresholds ``base**N .. base**(N-M)``).
        rule: ``"tighten"`` or ``"literal"`` (see :mod:`solvers.threshold_schedule`).
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
        super().__init__(threshold_schedule(initial_exponent, num_thresholds, target, base), rule)
        self.target = float(target)

    def update(self, estimated_cost: float) -> float:
        """Choose the threshold for this epoch's multiplier update from ``J_c``; return it."""
        return self.select(estimated_cost, stage_done=estimated_cost < self.current)
