"""Lagrange multipliers for the cost constraint J_c <= d (thesis Eqs. 2.4-2.5, 2.10).

Two update rules share one interface (``update(mean_episode_cost) -> multiplier``, a settable
``cost_limit`` and ``state_dict``):

* :class:`Lagrange` -- gradient ascent on the dual: one Adam (or SGD) step per epoch on the loss
  ``-lambda * (J_c - d)``, then projection onto ``[0, upper_bound]`` (OmniSafe/SafePO defaults:
  init 0.001, lr 0.035, Adam). With ``optimizer="sgd"`` the step is exactly Eq. 2.10,
  ``lambda <- lambda + lr * (J_c - d)``.
* :class:`PIDLagrange` -- the PID Lagrangian of Stooke et al. (2020) as parameterised in OmniSafe
  (Kp 0.1, Ki 0.01, Kd 0.01; EMA-smoothed P and D terms, D over a delay of epochs).

The self-paced variant changes ``cost_limit`` between updates (Alg. 1).
"""

from __future__ import annotations

import copy
import math
from collections import deque
from typing import Any

import torch

OPTIMIZERS = ("adam", "sgd")


def _check_limit(cost_limit: float) -> float:
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
        self.cost_limit = _check_limit(cost_limit)
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


class PIDLagrange:
    """PID Lagrangian (Stooke, Achiam & Abbeel 2020), OmniSafe parameterisation.

    ``e = J_c - d``; ``I <- max(0, I + Ki e)``; ``P`` and the cost used for ``D`` are
    exponential moving averages (``ema_alpha``); ``D = max(0, cost_ema - cost_ema[delay ago])``;
    ``lambda = clip(Kp P + I + Kd D, 0, upper_bound)``.

    Args:
        cost_limit: constraint threshold d.
        kp, ki, kd: PID gains.
        ema_alpha: smoothing of the P and D signals (0 = no smoothing).
        derivative_delay: epochs between the two costs compared by the D term.
        multiplier_init: initial value of the integral term (and thus lambda).
        upper_bound: optional cap on lambda.
    """

    def __init__(
        self,
        cost_limit: float,
        kp: float = 0.1,
        ki: float = 0.01,
        kd: float = 0.01,
        ema_alpha: float = 0.95,
        derivative_delay: int = 10,
        multiplier_init: float = 0.001,
        upper_bound: float | None = None,
    ) -> None:
        self.cost_limit = _check_limit(cost_limit)
        for name, gain in (("kp", kp), ("ki", ki), ("kd", kd)):
            if gain < 0:
                raise ValueError(f"{name} must be >= 0, got {gain}")
        if not 0.0 <= ema_alpha < 1.0:
            raise ValueError(f"ema_alpha must be in [0, 1), got {ema_alpha}")
        if derivative_delay < 1:
            raise ValueError(f"derivative_delay must be >= 1, got {derivative_delay}")
        if multiplier_init < 0:
            raise ValueError(f"multiplier_init must be >= 0, got {multiplier_init}")
        self.kp, self.ki, self.kd = kp, ki, kd
        self.ema_alpha = ema_alpha
        self.upper_bound = upper_bound
        self._integral = float(multiplier_init)
        self._error_ema = 0.0
        self._cost_ema = 0.0
        self._cost_history: deque[float] = deque([0.0], maxlen=derivative_delay)
        self._lambda = float(multiplier_init)

    @property
    def multiplier(self) -> float:
        """Current lambda (>= 0)."""
        return self._lambda

    def update(self, mean_episode_cost: float) -> float:
        """One PID step from the epoch's mean episode cost; returns the new lambda."""
        cost = float(mean_episode_cost)
        error = cost - self.cost_limit
        self._integral = max(0.0, self._integral + self.ki * error)
        a = self.ema_alpha
        self._error_ema = a * self._error_ema + (1 - a) * error
        self._cost_ema = a * self._cost_ema + (1 - a) * cost
        derivative = max(0.0, self._cost_ema - self._cost_history[0])
        raw = self.kp * self._error_ema + self._integral + self.kd * derivative
        upper = math.inf if self.upper_bound is None else self.upper_bound
        self._lambda = min(max(0.0, raw), upper)
        self._cost_history.append(self._cost_ema)
        return self._lambda

    def state_dict(self) -> dict[str, Any]:
        """All controller memory."""
        return {
            "lambda": self._lambda,
            "cost_limit": self.cost_limit,
            "integral": self._integral,
            "error_ema": self._error_ema,
            "cost_ema": self._cost_ema,
            "cost_history": list(self._cost_history),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self._lambda = state["lambda"]
        self.cost_limit = state["cost_limit"]
        self._integral = state["integral"]
        self._error_ema = state["error_ema"]
        self._cost_ema = state["cost_ema"]
        self._cost_history.clear()
        self._cost_history.extend(state["cost_history"])
