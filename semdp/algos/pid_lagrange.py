"""The PID Lagrangian (Stooke, Achiam & Abbeel 2020) as parameterised in OmniSafe (Kp 0.1, Ki
0.01, Kd 0.01; EMA-smoothed P and D terms, D over a delay of epochs): an alternative multiplier
rule for PPO-Lag / TRPO-Lag with the interface of :class:`semdp.algos.lagrangian.Lagrange`
(thesis Eqs. 2.4-2.5; ``algo/lagrange=pid``).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from semdp.algos.lagrangian import check_limit


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
        self.cost_limit = check_limit(cost_limit)
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
