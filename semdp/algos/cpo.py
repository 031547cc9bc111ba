"""Constrained Policy Optimisation (Achiam, Held, Tamar & Abbeel 2017), original derivation.

Per epoch, with ``g`` the gradient of the reward surrogate ``mean(ratio A_r)``, ``b`` that of the
cost surrogate ``mean(ratio A_c)``, ``H`` the Fisher matrix and ``c`` the constraint value, solve

    max_D  g'D   s.t.  c + b'D <= 0,   1/2 D'HD <= delta.

With ``x = H^-1 g``, ``p = H^-1 b``, ``q = g'x``, ``r = g'p``, ``s = b'p``, ``A = q - r^2/s`` and
``B = 2 delta - c^2/s`` the five cases are

* 4: ``b`` ~ 0 and ``c < 0`` -- no usable cost gradient, plain TRPO step;
* 3: ``c < 0, B < 0`` -- the whole trust region is feasible, plain TRPO step;
* 2: ``c < 0, B >= 0`` -- feasible, the constraint cuts the trust region: dual solution;
* 1: ``c >= 0, B >= 0`` -- infeasible but recoverable within the region: dual solution;
* 0: ``c >= 0, B < 0`` -- infeasible and unrecoverable: pure cost-decrease step
  ``D = -sqrt(2 delta / s) p``.

Dual (our sign convention, ``g`` is an *ascent* direction): ``D = (x - nu p) / lambda`` with
``nu = max(0, (lambda c + r) / s)``; ``lambda`` maximises ``f_a = -1/2 (A/lambda + B lambda) +
r c / s`` on the region where ``nu > 0`` or ``f_b = -1/2 (q/lambda + 2 delta lambda)`` where
``nu = 0``, each at its unconstrained maximiser projected onto its region. (safety-starter-agents
writes the same with ``g`` the gradient of the *loss*, which flips the sign of ``r``.)

Accept rule (backtracking, factor 0.8): mean KL <= delta, cost-surrogate increase <=
``max(-c, 0)``, and -- in cases 2-4 only -- the reward surrogate did not get worse; otherwise the
old parameters are kept.

Cost normalisation (documented choice): ``c = (J_c - d) / mean episode length``, as the original
code does, because the cost surrogate is a per-step mean; OmniSafe uses the raw episode-cost gap
``J_c - d``, which makes ``c`` about ``episode_length`` times larger relative to ``b`` and pushes
CPO into the recovery cases far more often.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, TypeVar

import gymnasium as gym
import torch
from torch.distributions import Normal
from torch.nn.utils import parameters_to_vector

from semdp.algos.gae import RolloutBatch
from semdp.algos.trpo import TRPO, conjugate_gradient

logger = logging.getLogger(__name__)

Vec = TypeVar("Vec")
B_SQ_NORM_TOL = 1e-8


@dataclass(frozen=True)
class CPODual:
    """Solution of the CPO dual: the case, the trust-region multiplier and the cost multiplier."""

    case: int
    lam: float
    nu: float


def _project(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


def cpo_dual(q: float, r: float, s: float, c: float, delta: float, b_sq_norm: float) -> CPODual:
    """Classify the CPO subproblem and solve its dual (see the module docstring).

    Args:
        q, r, s: ``g'H^-1 g``, ``g'H^-1 b``, ``b'H^-1 b``.
        c: constraint value (``<= 0`` is feasible).
        delta: trust-region radius.
        b_sq_norm: ``b'b``, to detect a vanishing cost gradient.

    Returns:
        :class:`CPODual`; for case 0 ``lam`` is ``nan`` and ``nu = sqrt(2 delta / s)``.
    """
    if delta <= 0:
        raise ValueError(f"delta must be > 0, got {delta}")
    eps = 1e-12
    trpo_lam = math.sqrt(max(q, eps) / (2 * delta))
    if b_sq_norm <= B_SQ_NORM_TOL or s <= eps:
        if c >= 0:
            logger.warning("CPO: infeasible (c=%.3g) but the cost gradient vanishes; TRPO step", c)
        return CPODual(4, trpo_lam, 0.0)
    big_a = max(q - r * r / s, eps)
    big_b = 2 * delta - c * c / s
    if c < 0 and big_b < 0:
        return CPODual(3, trpo_lam, 0.0)
    if c >= 0 and big_b < 0:
        return CPODual(0, math.nan, math.sqrt(2 * delta / s))
    case = 2 if c < 0 else 1
    # Regions of lambda >= 0 where nu = (lambda c + r)/s is positive (a) or not (b).
    inf = math.inf
    if c < 0:
        split = -r / c
        region_a = (0.0, split) if split > 0 else None
        region_b = (max(0.0, split), inf)
    elif c > 0:
        split = -r / c
        region_a = (max(0.0, split), inf)
        region_b = (0.0, split) if split >= 0 else None
    else:
        region_a, region_b = ((0.0, inf), None) if r > 0 else (None, (0.0, inf))
    candidates: list[tuple[float, float]] = []
    if region_a is not None:
        lam_a = max(_project(math.sqrt(big_a / max(big_b, eps)), *region_a), eps)
        candidates.append((-0.5 * (big_a / lam_a + big_b * lam_a) + r * c / s, lam_a))
    if region_b is not None:
        lam_b = max(_project(trpo_lam, *region_b), eps)
        candidates.append((-0.5 * (q / lam_b + 2 * delta * lam_b), lam_b))
    _, lam = max(candidates)
    nu = max(0.0, (lam * c + r) / s)
    return CPODual(case, lam, nu)


def cpo_step(x: Vec, p: Vec, dual: CPODual) -> Vec:
    """The parameter change ``D`` for a solved dual: ``(x - nu p)/lambda`` or ``-nu p``."""
    if dual.case == 0:
        return -dual.nu * p  # type: ignore[operator]
    return (x - dual.nu * p) / dual.lam  # type: ignore[operator]


class CPO(TRPO):
    """CPO on the episode-cost constraint ``J_c <= cost_limit``.

    Args:
        cost_limit: the limit d on the mean undiscounted episode cost.
        **kwargs: see :class:`~semdp.algos.trpo.TRPO`.
    """

    extra_columns = (*TRPO.extra_columns, "cpo_case", "cost_gap")

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        cost_limit: float = 25.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(envs, eval_envs, seed, **kwargs)
        if not math.isfinite(cost_limit) or cost_limit < 0:
            raise ValueError(f"cost_limit must be a finite number >= 0, got {cost_limit}")
        self.cost_limit = float(cost_limit)
        self._nu = 0.0

    def constraint_stats(self) -> dict[str, float]:
        """The cost dual nu (logged as the multiplier) and the limit."""
        return {"lagrange_multiplier": self._nu, "cost_threshold": self.cost_limit}

    def cost_gap(self) -> float:
        """``c = (J_c - d) / mean episode length`` (per-step units, as the original)."""
        length = self.last_ep_length if self.last_ep_length else float(self.n_steps)
        return (self.estimated_episode_cost() - self.cost_limit) / length

    def update_actor(self, batch: RolloutBatch) -> dict[str, float]:
        """Solve the CPO subproblem and line-search the step with the accept rule."""
        with torch.no_grad():
            d = self.actor.distribution(batch.obs)
            old = Normal(d.mean.clone(), d.stddev.clone(), validate_args=False)
        surr_r = self.surrogate(batch, batch.adv_r)
        g = self.flat_grad(surr_r)
        surr_c = self.surrogate(batch, batch.adv_c)
        b = self.flat_grad(surr_c)
        fvp = self.fisher_vector_product(batch, old)
        x = conjugate_gradient(fvp, g, self.cg_iters)
        c = self.cost_gap()
        b_sq = float(b @ b)
        if b_sq > B_SQ_NORM_TOL:
            p = conjugate_gradient(fvp, b, self.cg_iters)
            q, r, s = float(g @ x), float(g @ p), float(b @ p)
        else:
            p = torch.zeros_like(b)
            q, r, s = float(g @ x), 0.0, 0.0
        dual = cpo_dual(q, r, s, c, self.target_kl, b_sq)
        full_step = cpo_step(x, p, dual)
        self._nu = dual.nu
        old_params = parameters_to_vector(self._params()).detach()
        r_old, c_old = surr_r.item(), surr_c.item()

        def accept() -> bool:
            if float(self.mean_kl(batch.obs, old)) > self.target_kl:
                return False
            if float(self.surrogate(batch, batch.adv_c)) - c_old > max(-c, 0.0):
                return False
            return dual.case in (0, 1) or float(self.surrogate(batch, batch.adv_r)) >= r_old

        frac = self.line_search(old_params, full_step, accept)
        with torch.no_grad():
            kl = float(self.mean_kl(batch.obs, old))
            surr_new = float(self.surrogate(batch, batch.adv_r))
        return {
            "loss_pi": -surr_new, "kl": kl, "step_frac": frac,
            "cpo_case": dual.case, "cost_gap": c,
        }

    def state_dict(self) -> dict[str, Any]:
        """Adds the last cost dual (for logging continuity)."""
        return {**super().state_dict(), "nu": self._nu}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self._nu = state["nu"]
