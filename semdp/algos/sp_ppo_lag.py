"""Self-paced PPO-Lagrangian (thesis Alg. 1, Eqs. 2.8-2.10).

Each epoch, before the multiplier step, the threshold schedule picks ``d_i`` from the estimated
episode cost ``J_c`` (rule ``"tighten"`` or ``"literal"``, :class:`SelfPacedThresholds`), the
same Lagrange object receives it as its ``cost_limit`` and
then takes its step on ``J_c - d_i``. Only the dual update sees the threshold (§2.4.2: a constant
in the Lagrangian does not change the policy gradient). ``J_c`` is the mean undiscounted episode
cost of the epoch (the quantity Safety Gym limits), not the discounted one of Eq. 2.2.

The schedule and both threshold rules are :mod:`solvers.threshold_schedule`'s, shared with the
toy problem; :class:`SelfPacedThresholds` reads "stage done" as SP-PPO-Lag does: ``J_c`` is below
the current threshold. With ``"literal"`` the violation ``J_c - d_i`` is never negative while
``J_c`` is above the target, so lambda can only grow; with ``"tighten"`` (the default) lambda
relaxes while the policy is inside a loose threshold, which is the curriculum §2.4.1 describes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from semdp.algos.lagrangian import Multiplier
from semdp.algos.ppo import PPOLag
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


class SPPPOLag(PPOLag):
    """PPO-Lag whose cost limit follows a self-paced curriculum down to the target.

    Args:
        lagrange: the multiplier; its initial ``cost_limit`` is replaced by the schedule's.
        thresholds: the schedule (its ``target`` is the run's ``cost_limit``).
        **kwargs: see :class:`~semdp.algos.ppo.PPO`.
    """

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        lagrange: Multiplier,
        thresholds: SelfPacedThresholds,
        **kwargs: Any,
    ) -> None:
        super().__init__(envs, eval_envs, seed, lagrange, **kwargs)
        self.thresholds = thresholds
        self.lagrange.cost_limit = thresholds.current

    def before_update(self, stats: dict[str, float]) -> None:
        """Pick the threshold from J_c, hand it to the multiplier, take the dual step."""
        if stats["episodes"]:
            self.lagrange.cost_limit = self.thresholds.update(stats["ep_cost"])
            self.lagrange.update(stats["ep_cost"])

    def state_dict(self) -> dict[str, Any]:
        """Adds the schedule position."""
        return {**super().state_dict(), "thresholds": self.thresholds.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self.thresholds.load_state_dict(state["thresholds"])
