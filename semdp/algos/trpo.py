"""Trust Region Policy Optimisation (Schulman et al. 2015): the natural-gradient base of
TRPO-Lag and CPO.

One natural-gradient actor step per epoch on the whole batch: ``x = F^-1 g`` by conjugate
gradients on Fisher-vector products (Hessian of the mean KL, damping ``cg_damping``; written out
for the Gaussian actor, :mod:`semdp.algos.kernels.gaussian_fisher`), full step
``sqrt(2 delta / x'Fx) x``, backtracking line search (factor ``backtrack_coef``, at most
``backtrack_iters`` tries) accepting the first step with KL <= ``target_kl`` and an improved
surrogate, else keeping the old parameters. Critics: ``critic_iters`` minibatch passes at
``critic_lr`` (OmniSafe: 10 passes, lr 1e-3); the actor step draws no random numbers, so with
``parallel_critics`` the critics regress in a helper process meanwhile on exactly the
permutations they would draw afterwards.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import torch
from torch.distributions import Normal, kl_divergence
from torch.nn.utils import parameters_to_vector, vector_to_parameters

from semdp.algos.gae import RolloutBatch
from semdp.algos.on_policy import OnPolicyAlgorithm


def conjugate_gradient(
    matvec: Callable[[torch.Tensor], torch.Tensor],
    rhs: torch.Tensor,
    iters: int = 15,
    tol: float = 1e-10,
) -> torch.Tensor:
    """Approximately solve ``M x = rhs`` for symmetric positive definite ``M`` given ``M v``."""
    x = torch.zeros_like(rhs)
    r = rhs.clone()
    p = rhs.clone()
    rr = r @ r
    for _ in range(iters):
        if rr < tol:
            break
        mp = matvec(p)
        alpha = rr / (p @ mp)
        x += alpha * p
        r -= alpha * mp
        rr_new = r @ r
        p = r + (rr_new / rr) * p
        rr = rr_new
    return x


class TRPO(OnPolicyAlgorithm):
    """TRPO on an advantage given by :meth:`policy_advantage` (A_r here).

    Args:
        envs, eval_envs, seed, steps_per_epoch: see :class:`~semdp.algos.base.Algorithm`.
        target_kl: trust-region radius delta on the mean KL(old || new).
        cg_iters: conjugate-gradient iterations.
        cg_damping: Tikhonov damping added to the Fisher-vector product.
        backtrack_iters: maximum line-search steps.
        backtrack_coef: step shrink factor per line-search step.
        critic_lr: Adam learning rate of both critics (OmniSafe's TRPO: 1e-3).
        **kwargs: forwarded to :class:`~semdp.algos.on_policy.OnPolicyAlgorithm` (critic settings,
            ``gradients="autograd"`` for the double-backward Fisher-vector product;
            ``critic_minibatches`` defaults to the batch size / 128).
    """

    extra_columns = ("loss_pi", *OnPolicyAlgorithm.base_columns, "step_frac")

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        steps_per_epoch: int = 20_000,
        target_kl: float = 0.01,
        cg_iters: int = 15,
        cg_damping: float = 0.1,
        backtrack_iters: int = 15,
        backtrack_coef: float = 0.8,
        critic_lr: float = 1e-3,
        **kwargs: Any,
    ) -> None:
        kwargs.setdefault("critic_minibatches", max(1, steps_per_epoch // 128))
        super().__init__(envs, eval_envs, seed, steps_per_epoch, critic_lr=critic_lr, **kwargs)
        if target_kl <= 0:
            raise ValueError(f"target_kl must be > 0, got {target_kl}")
        if cg_iters < 1 or backtrack_iters < 1:
            raise ValueError(
                f"cg_iters and backtrack_iters must be >= 1, got {cg_iters}, {backtrack_iters}"
            )
        if not 0 < backtrack_coef < 1:
            raise ValueError(f"backtrack_coef must be in (0, 1), got {backtrack_coef}")
        self.target_kl, self.cg_iters, self.cg_damping = target_kl, cg_iters, cg_damping
        self.backtrack_iters, self.backtrack_coef = backtrack_iters, backtrack_coef
        self.kernel.check_fisher(self.actor, self.kl_hessian_product, cg_damping, self.obs_dim)

    # ----------------------------------------------------------------- pieces
    def policy_advantage(self, batch: RolloutBatch) -> torch.Tensor:
        """Advantage of the reward surrogate (TRPO-Lag overrides)."""
        return batch.adv_r

    def constraint_stats(self) -> dict[str, float]:
        """Multiplier/threshold columns (none for plain TRPO)."""
        return {}

    def before_update(self, stats: dict[str, float]) -> None:
        """Hook after the rollout, before the actor step (TRPO-Lag updates lambda)."""

    def _params(self) -> list[torch.nn.Parameter]:
        return list(self.actor.parameters())

    def surrogate(self, batch: RolloutBatch, adv: torch.Tensor) -> torch.Tensor:
        """``mean(ratio * adv)`` at the current actor parameters."""
        log_ratio = self.actor.log_prob(batch.obs, batch.actions) - batch.log_probs
        return (log_ratio.exp() * adv).mean()

    def flat_grad(self, value: torch.Tensor, **kwargs: Any) -> torch.Tensor:
        """Gradient of a scalar w.r.t. the actor parameters as one vector."""
        grads = torch.autograd.grad(value, self._params(), **kwargs)
        return torch.cat([g.reshape(-1) for g in grads])

    def mean_kl(self, obs: torch.Tensor, old: Normal) -> torch.Tensor:
        """Mean KL(old || current) over the observations ``obs``."""
        return kl_divergence(old, self.actor.distribution(obs)).sum(-1).mean()

    def fisher_vector_product(
        self, batch: RolloutBatch, old: Normal
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        """``v -> (F + damping I) v`` with F the Hessian of the mean KL at the old policy
        (the current parameters: called before the step)."""
        fisher = self.kernel.fisher(self.actor, batch.obs, self.cg_damping)
        if fisher is not None:  # the written-out product (gradients="written")
            return fisher
        return self.kl_hessian_product(batch.obs, old)

    def kl_hessian_product(
        self, obs: torch.Tensor, old: Normal
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        """The definition of :meth:`fisher_vector_product`: the Hessian of :meth:`mean_kl` by
        double backward, plus the damping (the written product, ``gradients="written"``, is
        checked against this at construction)."""
        grad_kl = self.flat_grad(self.mean_kl(obs, old), create_graph=True)

        def fvp(v: torch.Tensor) -> torch.Tensor:
            hv = self.flat_grad(grad_kl @ v, retain_graph=True)
            return hv + self.cg_damping * v

        return fvp

    def line_search(
        self,
        old_params: torch.Tensor,
        full_step: torch.Tensor,
        accept: Callable[[], bool],
    ) -> float:
        """Backtrack from the full step; return the accepted fraction (0 = old params kept)."""
        params = self._params()
        for j in range(self.backtrack_iters):
            frac = self.backtrack_coef**j
            vector_to_parameters(old_params + frac * full_step, params)
            with torch.no_grad():
                if accept():
                    return frac
        vector_to_parameters(old_params, params)
        return 0.0

    # ----------------------------------------------------------------- epoch
    def update_actor(self, batch: RolloutBatch) -> dict[str, float]:
        """One natural-gradient step on the surrogate of :meth:`policy_advantage`."""
        adv = self.policy_advantage(batch)
        with torch.no_grad():
            d = self.actor.distribution(batch.obs)
            old = Normal(d.mean.clone(), d.stddev.clone(), validate_args=False)
        surr = self.surrogate(batch, adv)
        g = self.flat_grad(surr)
        fvp = self.fisher_vector_product(batch, old)
        x = conjugate_gradient(fvp, g, self.cg_iters)
        xhx = float(x @ fvp(x))
        full_step = (2 * self.target_kl / max(xhx, 1e-12)) ** 0.5 * x
        old_params = parameters_to_vector(self._params()).detach()
        surr_old = surr.item()

        def accept() -> bool:
            kl = float(self.mean_kl(batch.obs, old))
            return kl <= self.target_kl and float(self.surrogate(batch, adv)) > surr_old

        frac = self.line_search(old_params, full_step, accept)
        with torch.no_grad():
            kl = float(self.mean_kl(batch.obs, old))
            surr_new = float(self.surrogate(batch, adv))
        return {"loss_pi": -surr_new, "kl": kl, "step_frac": frac}

    def train_epoch(self) -> dict[str, float]:
        """Rollout, (hook), GAE, natural-gradient actor step, critic regression."""
        stats = self.collect_rollout()
        self.before_update(stats)
        batch = self.compute_batch()
        with self.timer.phase("update"):
            critic_job = self.critics.start(batch, skip=0)
            actor_stats = self.update_actor(batch)
            critic_stats = self.critics.finish(batch, critic_job, drawn=0)
            with torch.no_grad():
                entropy = float(self.actor.distribution(batch.obs[:1]).entropy().sum())
        self.epoch += 1
        return {**stats, **self.constraint_stats(), **actor_stats, **critic_stats,
                "entropy": entropy}
