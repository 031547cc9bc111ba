"""The Lagrangian piece of PPO-Lag and TRPO-Lag (Ray, Achiam & Amodei 2019; thesis Eqs. 2.4-2.7,
2.10): a multiplier on the constraint J_c <= d and the advantage it weighs.

:class:`Lagrange` is gradient ascent on the dual: one Adam (or SGD) step per epoch on the loss
``-lambda * (J_c - d)``, then projection onto ``[0, upper_bound]`` (OmniSafe/SafePO defaults:
init 0.001, lr 0.035, Adam); with ``optimizer="sgd"`` the step is exactly Eq. 2.10,
``lambda <- lambda + lr * (J_c - d)``. The PID rule with the same interface
(``update(mean_episode_cost) -> multiplier``, a settable ``cost_limit``, ``state_dict``) is
:class:`~semdp.algos.pid_lagrange.PIDLagrange`; the self-paced variant changes ``cost_limit``
between updates (Alg. 1, :mod:`semdp.algos.sp_ppo_lag`).

Per epoch the multiplier is updated first, from the mean undiscounted cost of the episodes that
finished during this epoch's rollout (OmniSafe order; skipped when none finished); then the actor
ascends the combined advantage ``(A_r - lambda A_c) / (1 + lambda)``.
"""

from __future__ import annotations

import copy
import math
from typing import Any, Protocol

import gymnasium as gym
import torch

from semdp.algos.gae import RolloutBatch

OPTIMIZERS = ("adam", "sgd")


class Multiplier(Protocol):
    """What the algorithms need of a multiplier rule (:class:`Lagrange`, ``PIDLagrange``)."""

    cost_limit: float

    @property
    def multiplier(self) -> float: ...

    def update(self, mean_episode_cost: float) -> float: ...

    def state_dict(self) -> dict[str, Any]: ...

    def load_state_dict(self, state: dict[str, Any]) -> None: ...


def check_limit(cost_limit: float) -> float:
    cost_limit = float(cost_limit)
    if not math.isfinite(cost_limit) or cost_limit < 0:
        raise ValueError(f"cost_limit must be a finite number >= 0, got {cost_limit}")
    return cost_limit


class Lagrange:
    """Projected dual ascent on a scalar multiplier.

    Args:
        cost_limit: constraint threshold d on the mean undiscounted episode cost.
        multiplier_init: initial lambda (>= 0).
        lr: dual learning rate (beta in Eq. 2.10).
        optimizer: ``"adam"`` (OmniSafe) or ``"sgd"`` (plain Eq. 2.10).
        upper_bound: optional cap on lambda (``None`` = no cap).
    """

    def __init__(
        self,
        cost_limit: float,
        multiplier_init: float = 0.001,
        lr: float = 0.035,
        optimizer: str = "adam",
        upper_bound: float | None = None,
    ) -> None:
        self.cost_limit = check_limit(cost_limit)
        if multiplier_init < 0:
            raise ValueError(f"multiplier_init must be >= 0, got {multiplier_init}")
        if lr <= 0:
            raise ValueError(f"lr must be > 0, got {lr}")
        if optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer must be one of {OPTIMIZERS}, got {optimizer!r}")
        if upper_bound is not None and upper_bound < multiplier_init:
            raise ValueError(
                f"upper_bound ({upper_bound}) must be >= multiplier_init ({multiplier_init})"
            )
        self.upper_bound = upper_bound
        self._lambda = torch.nn.Parameter(torch.tensor(float(multiplier_init)))
        opt_cls = torch.optim.Adam if optimizer == "adam" else torch.optim.SGD
        self._optimizer = opt_cls([self._lambda], lr=lr)

    @property
    def multiplier(self) -> float:
        """Current lambda (>= 0)."""
        return float(self._lambda.detach())

    def update(self, mean_episode_cost: float) -> float:
        """One dual step from the epoch's mean episode cost J_c; returns the new lambda.

        The loss ``-lambda (J_c - d)`` has gradient ``-(J_c - d)``, so lambda grows while the
        constraint is violated and shrinks (down to 0) while it is satisfied.
        """
        violation = float(mean_episode_cost) - self.cost_limit
        self._optimizer.zero_grad()
        loss = -self._lambda * violation
        loss.backward()
        self._optimizer.step()
        with torch.no_grad():
            self._lambda.clamp_(min=0.0, max=self.upper_bound)
        return self.multiplier

    def state_dict(self) -> dict[str, Any]:
        """Multiplier, limit and optimiser state."""
        return {
            "lambda": self.multiplier,
            "cost_limit": self.cost_limit,
            "optimizer": copy.deepcopy(self._optimizer.state_dict()),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        with torch.no_grad():
            self._lambda.fill_(state["lambda"])
        self.cost_limit = state["cost_limit"]
        self._optimizer.load_state_dict(state["optimizer"])


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
        lagrange: a :class:`Lagrange` or :class:`~semdp.algos.pid_lagrange.PIDLagrange` (its
            ``cost_limit`` is the run's).
        **kwargs: the constructor arguments of the unconstrained algorithm.
    """

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        lagrange: Multiplier,
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
