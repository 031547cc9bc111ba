"""Adam on a scalar (Kingma & Ba): the primal optimiser of the toy problem's Lagrangian dynamics
and, optionally, its multiplier's (thesis §2.5.1, Fig. 2.1; Eqs. 2.4-2.5)."""

from __future__ import annotations

import math


class ScalarAdam:
    """Adam (Kingma & Ba) on a scalar, with a learning-rate multiplier per step."""

    def __init__(self, lr: float, beta1: float, beta2: float, eps: float = 1e-8) -> None:
        self.lr, self.beta1, self.beta2, self.eps = lr, beta1, beta2, eps
        self.m = 0.0
        self.v = 0.0
        self.t = 0

    def step(self, grad: float, lr_scale: float = 1.0) -> float:
        """Return the descent step ``lr * m_hat / (sqrt(v_hat) + eps)`` for gradient ``grad``."""
        self.t += 1
        self.m = self.beta1 * self.m + (1.0 - self.beta1) * grad
        self.v = self.beta2 * self.v + (1.0 - self.beta2) * grad * grad
        m_hat = self.m / (1.0 - self.beta1**self.t)
        v_hat = self.v / (1.0 - self.beta2**self.t)
        return lr_scale * self.lr * m_hat / (math.sqrt(v_hat) + self.eps)
