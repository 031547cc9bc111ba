"""The Lagrangian piece shared by PPO-Lag and TRPO-Lag (Ray, Achiam & Amodei 2019; Eqs. 2.4-2.7).

Per epoch the multiplier is updated first, from the mean undiscounted cost of the episodes that
finished during this epoch's rollout (OmniSafe order; skipped when none finished); then the actor
ascends the combined advantage ``(A_r - lambda A_c) / (1 + lambda)``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch

from semdp.common.buffers import RolloutBatch
from semdp.common.lagrange import Lagrange, PIDLagrange


def combined_advantage(adv_r: torch.Tensor, adv_c: torch.Tensor, multiplier: float) -> torch.Tensor:
    """``(A_r - lambda A_c) / (1 + lambda)``: the Lagrangian advantage, rescaled so its size does
    not grow with lambda (OmniSafe, SafePO, safety-starter-agents)."""
    if multiplier < 0:
        raise ValueError(f"multiplier must be >= 0, got {multiplier}")
    return (adv_r - multiplier * adv_c) / (1.0 + multiplier)


class LagrangianMixin:
    """Adds a Lagrange multiplier on the episode-cost constraint to an on-policy algorithm.

    Put it first in the bases (``class PPOLag(LagrangianMixin, PPO)``) so its hooks override the
    unconstrained algorithm's.

    Args:
        lagrange: a :class:`~semdp.common.lagrange.Lagrange` or
            :class:`~semdp.common.lagrange.PIDLagrange` (its ``cost_limit`` is the run's).
        **kwargs: the constructor arguments of the unconstrained algorithm.
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
        if not hasattr(lagrange, "update"):
            raise ValueError(f"lagrange must be a Lagrange or PIDLagrange, got {type(lagrange)}")
        self.lagrange = lagrange

    def before_update(self, stats: dict[str, float]) -> None:
        """Dual step from this epoch's mean episode cost."""
        if stats["episodes"]:
            self.lagrange.update(stats["ep_cost"])

    def policy_advantage(self, batch: RolloutBatch) -> torch.Tensor:
        """Combined advantage with the current multiplier."""
        return combined_advantage(batch.adv_r, batch.adv_c, self.lagrange.multiplier)

    def constraint_stats(self) -> dict[str, float]:
        """lambda and the threshold in force."""
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
