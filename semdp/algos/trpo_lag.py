"""TRPO-Lagrangian (Ray, Achiam & Amodei 2019): TRPO on ``(A_r - lambda A_c) / (1 + lambda)``
with the multiplier updated once per epoch before the actor step (same rule as PPO-Lag)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch

from semdp.algos.ppo_lag import combined_advantage
from semdp.algos.trpo import TRPO
from semdp.common.buffers import RolloutBatch
from semdp.common.lagrange import Lagrange, PIDLagrange


class TRPOLag(TRPO):
    """TRPO with a Lagrange multiplier on the episode-cost constraint.

    Args:
        lagrange: the multiplier (its ``cost_limit`` is the run's).
        **kwargs: see :class:`~semdp.algos.trpo.TRPO`.
    """

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        lagrange: Lagrange | PIDLagrange,
        **kwargs: Any,
    ) -> None:
        super().__init__(envs, eval_envs, seed, **kwargs)
        self.lagrange = lagrange

    def before_update(self, stats: dict[str, float]) -> None:
        """Dual step from this epoch's mean episode cost."""
        if stats["episodes"]:
            self.lagrange.update(stats["ep_cost"])

    def policy_advantage(self, batch: RolloutBatch) -> torch.Tensor:
        """Combined advantage with the current multiplier."""
        return combined_advantage(batch.adv_r, batch.adv_c, self.lagrange.multiplier)

    def constraint_stats(self) -> dict[str, float]:
        """lambda and the limit."""
        return {
            "lagrange_multiplier": self.lagrange.multiplier,
            "cost_threshold": self.lagrange.cost_limit,
        }

    def state_dict(self) -> dict[str, Any]:
        """Adds the multiplier state."""
        return {**super().state_dict(), "lagrange": self.lagrange.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self.lagrange.load_state_dict(state["lagrange"])
