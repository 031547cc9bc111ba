"""PPO-Lagrangian (Ray, Achiam & Amodei 2019; thesis Eqs. 2.4-2.7): PPO plus a Lagrange object.

Per epoch: the multiplier is updated first, from the mean undiscounted cost of the episodes that
finished during this epoch's rollout (OmniSafe order; skipped when none finished), then the actor
ascends the combined advantage ``(A_r - lambda A_c) / (1 + lambda)`` with the PPO clip.
"""

from __future__ import annotations

from semdp.algos.lagrangian import LagrangianMixin
from semdp.algos.ppo import PPO


class PPOLag(LagrangianMixin, PPO):
    """PPO with a Lagrange multiplier on the episode-cost constraint.

    Args:
        lagrange: a :class:`~semdp.common.lagrange.Lagrange` or
            :class:`~semdp.common.lagrange.PIDLagrange` (its ``cost_limit`` is the run's).
        **kwargs: see :class:`~semdp.algos.ppo.PPO`.
    """
