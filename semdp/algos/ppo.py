"""PPO and PPO-Lagrangian: clipped surrogate (Schulman et al. 2017; thesis Eq. 2.6) and the
Lagrange multiplier on the episode cost (Ray, Achiam & Amodei 2019; thesis Eqs. 2.4-2.7).

Update scheme (recorded choice, docs/training.md, "Algorithms and recorded choices"): CleanRL-style
``update_iters`` passes x ``num_minibatches`` minibatches, gradient-norm clip 0.5, actor learning
rate linearly decayed to 0 over the run, early stop of the passes when the approximate KL on the
whole batch exceeds ``target_kl`` (OmniSafe's per-pass check). The cost critic is trained as well
so that PPO logs the same columns as its constrained variants. The actor's loss is defined once,
here (:meth:`PPO.actor_loss`), and runs through autograd by default; the presets
(``conf/algo/ppo.yaml``) opt into a kernel with its derivatives written out
(``gradients="written"``, :mod:`semdp.algos.kernels.ppo_actor_step`), which is checked against
:meth:`PPO.actor_loss` when the algorithm is built and refuses to run if they disagree.

With ``parallel_critics`` the critics regress in a helper process during the actor passes. Their
permutations come from torch's generator after the actor's, whose number is only known when
the KL check stops the passes; the helper starts on the permutations that follow
``update_iters`` passes (no early stop, the common case) and is cancelled and replaced by a
regression here when the passes stop earlier, so the result is the same either way.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch

from semdp.algos.gae import RolloutBatch
from semdp.algos.lagrangian import LagrangianMixin
from semdp.algos.on_policy import OnPolicyAlgorithm
from semdp.common.optim import FlatAdam, clip_grad_norm


class PPO(OnPolicyAlgorithm):
    """PPO-Clip on the reward advantage.

    Args:
        envs, eval_envs, seed, steps_per_epoch: see :class:`~semdp.algos.base.Algorithm`.
        actor_lr: Adam learning rate of the actor.
        lr_decay: linear decay of ``actor_lr`` to 0 over the run.
        clip_range: PPO clip epsilon.
        update_iters: passes over the batch per epoch.
        num_minibatches: minibatches per pass.
        target_kl: early-stop threshold on KL(old || new) (``None`` = off).
        ent_coef: entropy bonus.
        **kwargs: forwarded to :class:`~semdp.algos.on_policy.OnPolicyAlgorithm`.
    """

    extra_columns = ("loss_pi", *OnPolicyAlgorithm.base_columns, "update_passes")

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        steps_per_epoch: int = 20_000,
        actor_lr: float = 3e-4,
        lr_decay: bool = True,
        clip_range: float = 0.2,
        update_iters: int = 10,
        num_minibatches: int = 32,
        target_kl: float | None = 0.02,
        ent_coef: float = 0.0,
        **kwargs: Any,
    ) -> None:
        kwargs.setdefault("critic_iters", update_iters)
        kwargs.setdefault("critic_minibatches", num_minibatches)
        super().__init__(envs, eval_envs, seed, steps_per_epoch, **kwargs)
        if not 0 < clip_range < 1:
            raise ValueError(f"clip_range must be in (0, 1), got {clip_range}")
        if update_iters < 1 or num_minibatches < 1:
            raise ValueError(
                f"update_iters and num_minibatches must be >= 1, got {update_iters}, "
                f"{num_minibatches}"
            )
        if num_minibatches > self.steps_per_epoch:
            raise ValueError(
                f"num_minibatches ({num_minibatches}) exceeds steps_per_epoch "
                f"({self.steps_per_epoch})"
            )
        self.actor_lr, self.lr_decay = actor_lr, lr_decay
        self.clip_range, self.update_iters = clip_range, update_iters
        self.num_minibatches, self.target_kl, self.ent_coef = num_minibatches, target_kl, ent_coef
        self.actor_optimizer = FlatAdam(self.actor.parameters(), lr=actor_lr)
        self.kernel.check_ppo(self.actor, self.actor_optimizer, self.actor_loss, clip_range,
                              ent_coef, self.obs_dim, self.act_dim)

    def policy_advantage(self, batch: RolloutBatch) -> torch.Tensor:
        """The advantage the actor ascends; PPO uses A_r (PPO-Lag overrides)."""
        return batch.adv_r

    def constraint_stats(self) -> dict[str, float]:
        """Multiplier and threshold columns (none for unconstrained PPO)."""
        return {}

    def before_update(self, stats: dict[str, float]) -> None:
        """Hook run after the rollout, before the policy update (PPO-Lag updates lambda)."""

    def train_epoch(self) -> dict[str, float]:
        """Rollout, (hook), GAE, clipped-surrogate passes, critic regression."""
        stats = self.collect_rollout()
        self.before_update(stats)
        batch = self.compute_batch()
        with self.timer.phase("update"):
            out = self._update(batch)
        self.epoch += 1
        return {**stats, **self.constraint_stats(), **out}

    def actor_loss(self, obs: torch.Tensor, actions: torch.Tensor, old_log_probs: torch.Tensor,
                   advantages: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loss, entropy)`` of a minibatch: the clipped surrogate of thesis Eq. 2.6, negated,
        less ``ent_coef`` times the policy's entropy. This is the definition: the written step
        (:mod:`semdp.algos.kernels.ppo_actor_step`, ``gradients="written"``) takes its gradient by
        hand and is checked against it at construction (an edit here that the kernel does not
        mirror fails there, naming the kernel and ``algo.gradients=autograd``)."""
        dist = self.actor.distribution(obs)
        ratio = (dist.log_prob(actions).sum(-1) - old_log_probs).exp()
        clipped = ratio.clamp(1 - self.clip_range, 1 + self.clip_range)
        surrogate = torch.min(ratio * advantages, clipped * advantages)
        entropy = dist.entropy().sum(-1).mean()
        return -surrogate.mean() - self.ent_coef * entropy, entropy

    def _update(self, batch: RolloutBatch) -> dict[str, float]:
        """Clipped-surrogate passes (critics meanwhile in the helper, if any), then critics."""
        critic_job = self.critics.start(batch, skip=self.update_iters)  # None: plain path
        adv = self.policy_advantage(batch)
        if self.lr_decay:
            frac = 1.0 - self.epoch / max(self.total_epochs, 1)
            for group in self.actor_optimizer.param_groups:
                group["lr"] = self.actor_lr * max(frac, 0.0)
        n = batch.obs.shape[0]
        mb = max(1, n // self.num_minibatches)
        actor_params = list(self.actor.parameters())
        written = self.kernel.ppo_step(self.actor, self.actor_optimizer)  # None: autograd
        loss_pi, entropy, kl, passes = torch.tensor(0.0), torch.tensor(0.0), 0.0, 0
        for _ in range(self.update_iters):
            perm = torch.randperm(n)  # one gather per pass; minibatches are slices of it
            obs, actions, old_log_probs, advs = (x[perm] for x in (batch.obs, batch.actions,
                                                                   batch.log_probs, adv))
            for start in range(0, n, mb):
                idx = slice(start, start + mb)
                if written is not None:
                    loss_pi, entropy = written.step(
                        obs[idx], actions[idx], old_log_probs[idx], advs[idx],
                        self.clip_range, self.ent_coef, self.max_grad_norm)
                    continue
                loss_pi, entropy = self.actor_loss(obs[idx], actions[idx], old_log_probs[idx],
                                                   advs[idx])
                self.actor_optimizer.zero_grad()
                loss_pi.backward()
                if self.max_grad_norm is not None:
                    clip_grad_norm(actor_params, self.max_grad_norm)
                self.actor_optimizer.step()
            passes += 1
            with torch.no_grad():  # k3 estimator of KL(old || new), Schulman's blog
                log_ratio = self.actor.log_prob(batch.obs, batch.actions) - batch.log_probs
                kl = float(((log_ratio.exp() - 1) - log_ratio).mean())
            if self.target_kl is not None and kl > self.target_kl:
                break
        critic_stats = self.critics.finish(batch, critic_job, drawn=passes)
        return {
            **critic_stats, "loss_pi": loss_pi.item(), "entropy": entropy.item(), "kl": kl,
            "update_passes": passes,
        }

    def state_dict(self) -> dict[str, Any]:
        """Adds the actor optimiser."""
        return {**super().state_dict(), "actor_optimizer": self.actor_optimizer.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self.actor_optimizer.load_state_dict(state["actor_optimizer"])


class PPOLag(LagrangianMixin, PPO):
    """PPO with a Lagrange multiplier on the episode-cost constraint: per epoch the multiplier
    steps first, from the mean cost of the episodes that finished in this rollout (OmniSafe
    order), then the actor ascends ``(A_r - lambda A_c) / (1 + lambda)`` with the PPO clip.

    Args:
        lagrange: a :class:`~semdp.algos.lagrangian.Lagrange` or
            :class:`~semdp.algos.pid_lagrange.PIDLagrange` (its ``cost_limit`` is the run's).
        **kwargs: see :class:`PPO`.
    """
