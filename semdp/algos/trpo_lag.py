"""TRPO-Lagrangian (Ray, Achiam & Amodei 2019): TRPO on ``(A_r - lambda A_c) / (1 + lambda)``
with the multiplier updated once per epoch before the actor step (same rule as PPO-Lag)."""

from __future__ import annotations

from semdp.algos.lagrangian import LagrangianMixin
from semdp.algos.trpo import TRPO


class TRPOLag(LagrangianMixin, TRPO):
    """TRPO with a Lagrange multiplier on the episode-cost constraint.

    Args:
        lagrange: the multiplier (its ``cost_limit`` is the run's).
        **kwargs: see :class:`~semdp.algos.trpo.TRPO`.
    """
