"""Self-paced PPO-Lagrangian (thesis Alg. 1, Eqs. 2.8-2.10).

Each epoch, before the multiplier step, the threshold schedule picks ``d_i`` from the estimated
episode cost ``J_c`` (rule ``"tighten"`` or ``"literal"``, see
:mod:`semdp.common.self_paced`), the same Lagrange object receives it as its ``cost_limit`` and
then takes its step on ``J_c - d_i``. Only the dual update sees the threshold (§2.4.2: a constant
in the Lagrangian does not change the policy gradient). ``J_c`` is the mean undiscounted episode
cost of the epoch (the quantity Safety Gym limits), not the discounted one of Eq. 2.2.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from semdp.algos.ppo_lag import PPOLag
from semdp.common.lagrange import Lagrange, PIDLagrange
from semdp.common.self_paced import SelfPacedThresholds


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
        lagrange: Lagrange | PIDLagrange,
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
