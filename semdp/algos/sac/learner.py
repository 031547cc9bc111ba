"""The learning half of SAC (Haarnoja et al. 2018): SAC's only update, run in the training process
or in a process of its own (docs/semdp.md, "The main job's loop"; the high level of thesis
Alg. 2).

:class:`SACLearner` owns the actor, the fused twin critic
(:class:`~semdp.algos.sac.twin_q.FusedTwinQ`) and its target, the three optimisers and the
temperature, and runs ``n`` gradient updates on the replay rows it is told are filled, for
every loop of :class:`semdp.algos.sac.SAC`. The
update is CleanRL's: clipped double-Q target with the entropy term, policy delay
``policy_frequency`` (then that many actor and temperature steps, or ``policy_steps``),
Polyak-averaged target critics; it only drops work whose result is discarded (critic weight
gradients of the actor loss). Randomness (minibatch indices, the policy's reparameterisation
noise) comes from the learner's own generator, so the learner gives
the same numbers in the training process and in a process of its own.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from semdp.algos.kernels import sac_written
from semdp.algos.sac.twin_q import FusedTwinQ
from semdp.common.networks import SquashedGaussianActor
from semdp.common.optim import LeanAdam

#: Log columns a round of updates reports (``progress.csv`` columns of SAC).
LOG_KEYS: tuple[str, ...] = ("loss_q", "q_mean", "loss_pi", "entropy")
#: How the learner computes its gradients: autograd, or written out
#: (:mod:`semdp.algos.kernels.sac_written`: the same floats without the graph).
GRADIENTS: tuple[str, ...] = ("autograd", "written")


@dataclass(frozen=True)
class LearnerSettings:
    """Everything needed to rebuild a :class:`SACLearner` in another process (SAC's arguments)."""

    obs_dim: int
    act_dim: int
    hidden_sizes: tuple[int, ...]
    actor_lr: float
    critic_lr: float
    gamma: float
    tau: float
    batch_size: int
    policy_frequency: int
    alpha: float
    autotune: bool
    target_entropy: float
    alpha_lr: float
    seed: int
    policy_steps: int = 0  # actor updates each policy_frequency critic updates (0: as many)
    n_step: int = 1  # > 1: rows are n-step returns bootstrapping gamma^horizon ahead
    critic_layer_norm: bool = False  # LayerNorm before the critics' hidden ReLUs
    gradients: str = "autograd"  # autograd | written (semdp.algos.kernels.sac_written)


def networks_state(owner: Any) -> dict[str, Any]:
    """The checkpoint entries of SAC's networks, optimisers and temperature (``owner``: a
    :class:`SACLearner` or the sequential :class:`~semdp.algos.sac.SAC`, same attribute names)."""
    return {
        "actor": owner.actor.state_dict(),
        "critic": owner.critic.state_dict(),
        "critic_target": owner.critic_target.state_dict(),
        "actor_optimizer": owner.actor_optimizer.state_dict(),
        "critic_optimizer": owner.critic_optimizer.state_dict(),
        "log_alpha": float(owner.log_alpha.detach()),
        "alpha_optimizer": owner.alpha_optimizer.state_dict(),
    }


class SACLearner:
    """SAC's networks, optimisers and update on a replay storage of torch tensors.

    Args:
        settings: sizes and hyper-parameters.
        storage: the replay tensors ``obs``, ``next_obs``, ``actions``, ``rewards``,
            ``terminated`` and, for n-step rows, ``horizons``
            (:class:`~semdp.algos.sac.replay.SharedReplayBuffer.tensors`).
        actor: the actor to train (built here when None).
    """

    def __init__(
        self,
        settings: LearnerSettings,
        storage: dict[str, torch.Tensor],
        actor: SquashedGaussianActor | None = None,
    ) -> None:
        s = settings
        if s.gradients not in GRADIENTS:
            raise ValueError(f"gradients must be one of {list(GRADIENTS)}, got {s.gradients!r}")
        self.settings = s
        self.storage = storage
        hidden = tuple(s.hidden_sizes)
        self.actor = actor if actor is not None else SquashedGaussianActor(
            s.obs_dim, s.act_dim, hidden)
        if s.gradients == "written":
            sac_written.check_supported(self.actor, s.critic_layer_norm)
        self.critic = FusedTwinQ(s.obs_dim, s.act_dim, hidden, layer_norm=s.critic_layer_norm)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        # Adam with the fused CPU kernel, called without the optimiser's per-step overhead
        self.actor_optimizer = LeanAdam(self.actor.parameters(), s.actor_lr)
        self.critic_optimizer = LeanAdam(self.critic.parameters(), s.critic_lr)
        self.log_alpha = torch.tensor(math.log(s.alpha), requires_grad=True)
        self.alpha_optimizer = LeanAdam([self.log_alpha], lr=s.alpha_lr)
        self.generator = torch.Generator().manual_seed(int(s.seed))
        self.updates = 0
        self._critic_params = list(self.critic.parameters())
        self._target_params = list(self.critic_target.parameters())
        if s.gradients == "written":
            self.check_written()

    def check_written(self) -> None:
        """The written kernel (:mod:`semdp.algos.kernels.sac_written`) against this learner's own
        losses (:meth:`critic_loss`, :meth:`actor_loss`, :meth:`alpha_loss`) on a random
        minibatch from a generator of its own (the run's streams are not touched): loss values
        and gradients must be equal bit for bit, as they are by construction of the kernel. An
        edit to a loss that the kernel does not mirror raises here."""
        s = self.settings
        gen = torch.Generator().manual_seed(0)
        obs, actions = (torch.randn(s.batch_size, n, generator=gen)
                        for n in (s.obs_dim, s.act_dim))
        target = torch.randn(s.batch_size, generator=gen)
        noise = torch.randn(s.batch_size, s.act_dim, generator=gen)
        frozen = [p.detach() for p in self._critic_params]
        alpha = self.log_alpha.detach().exp()
        loss_q, _ = self.critic_loss(obs, actions, target)
        loss_pi, logp = self.actor_loss(obs, noise, alpha, frozen)
        expected = {
            "the critic loss": [loss_q.detach()],
            "the critic gradient": list(torch.autograd.grad(loss_q, self._critic_params)),
            "the actor loss": [loss_pi.detach()],
            "the actor gradient": list(torch.autograd.grad(loss_pi,
                                                           list(self.actor.parameters()))),
            "the temperature gradient": list(torch.autograd.grad(self.alpha_loss(logp),
                                                                 [self.log_alpha])),
        }
        with torch.no_grad():
            w_loss_q, _, w_grad_q = sac_written.critic_loss_grads(
                self._critic_params, self.critic.hidden, obs, actions, target)
            w_loss_pi, w_logp, w_grad_pi = sac_written.actor_loss_grads(
                self.actor, self._critic_params, self.critic.hidden, obs, noise, alpha)
            written = {
                "the critic loss": [w_loss_q], "the critic gradient": list(w_grad_q),
                "the actor loss": [w_loss_pi], "the actor gradient": list(w_grad_pi),
                "the temperature gradient": [sac_written.alpha_loss_grad(w_logp,
                                                                         s.target_entropy)],
            }
        for what, tensors in expected.items():
            if len(tensors) != len(written[what]) or not all(
                    torch.equal(a, b) for a, b in zip(tensors, written[what], strict=True)):
                raise sac_written.KernelMismatch(
                    f"the written kernel semdp.algos.kernels.sac_written disagrees with "
                    f"SACLearner's own loss on a random minibatch: {what} differs (the kernel "
                    f"gives autograd's floats bit for bit, so it must be equal). The kernel "
                    f"restates SAC's derivatives by hand: mirror the edit in "
                    f"semdp/algos/kernels/sac_written.py, or turn the kernel off with the config "
                    f"option algo.gradients=autograd (or null).")

    # ----------------------------------------------------------------- the update
    def _noise(self, batch: int) -> torch.Tensor:
        """The reparameterisation noise of one policy sample (this learner's generator)."""
        return torch.randn((batch, self.settings.act_dim), generator=self.generator)

    def _policy(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A reparameterised sample of the squashed policy and its log-probability
        (:meth:`SquashedGaussianActor.reparameterised` with this learner's noise)."""
        return self.actor(obs, noise=self._noise(obs.shape[0]))

    def update(self, size: int, logs: dict[str, list[torch.Tensor]]) -> None:
        """One critic update on a minibatch of the first ``size`` rows (+ the delayed actor and
        temperature updates); appends the logged scalars to ``logs``."""
        s = self.settings
        idx = torch.randint(0, size, (s.batch_size,), generator=self.generator)
        st = self.storage
        obs, actions = st["obs"].index_select(0, idx), st["actions"].index_select(0, idx)
        rewards, next_obs = st["rewards"].index_select(0, idx), st["next_obs"].index_select(0, idx)
        terminated = st["terminated"].index_select(0, idx)
        alpha = self.log_alpha.detach().exp()
        with torch.no_grad():
            next_a, next_logp = self._policy(next_obs)
            q_next = self.critic_target(next_obs, next_a, self._target_params)
            soft_v = q_next.min(0).values - alpha * next_logp
            if s.n_step > 1:  # n-step rows (semdp.algos.sac.n_step): bootstrap gamma^m ahead
                discount = s.gamma ** st["horizons"].index_select(0, idx)
                target = rewards + discount * (1.0 - terminated) * soft_v
            else:
                target = rewards + s.gamma * (1.0 - terminated) * soft_v
        if s.gradients == "written":
            self._update_written(obs, actions, target, logs)
        else:
            self._update_autograd(obs, actions, target, logs)
        with torch.no_grad():
            torch._foreach_lerp_(self._target_params, self._critic_params, s.tau)

    # ----------------------------------------------------------------- SAC's losses
    def critic_loss(self, obs: torch.Tensor, actions: torch.Tensor,
                    target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loss_q, Q)``: the twin critics' squared errors on the soft target, summed over
        the two critics (Haarnoja et al. 2018, Eq. 5)."""
        q = self.critic(obs, actions, self._critic_params)
        return (q - target).square().mean(1).sum(), q

    def actor_loss(self, obs: torch.Tensor, noise: torch.Tensor, alpha: torch.Tensor,
                   critic_params: list[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loss_pi, log pi)``: ``mean(alpha log pi(a|s) - min(Q1, Q2)(s, a))`` with ``a``
        reparameterised by ``noise`` (Haarnoja et al. 2018, Eq. 7), the critic at
        ``critic_params`` (held fixed: detached tensors)."""
        action, log_prob = self.actor(obs, noise=noise)
        q_pi = self.critic(obs, action, critic_params).min(0).values
        return (alpha * log_prob - q_pi).mean(), log_prob

    def alpha_loss(self, log_prob: torch.Tensor) -> torch.Tensor:
        """The temperature loss ``-mean(log_alpha (log pi + target entropy))`` (Haarnoja et al.
        2018b, Eq. 18)."""
        return -(self.log_alpha * (log_prob.detach() + self.settings.target_entropy)).mean()

    def _update_autograd(self, obs: torch.Tensor, actions: torch.Tensor, target: torch.Tensor,
                         logs: dict[str, list[torch.Tensor]]) -> None:
        """The critic step and the delayed actor and temperature steps, gradients by autograd."""
        s = self.settings
        loss_q, q = self.critic_loss(obs, actions, target)
        self.critic_optimizer.zero_grad(set_to_none=True)
        loss_q.backward()
        self.critic_optimizer.step()
        self.updates += 1
        logs["loss_q"].append(loss_q.detach())
        logs["q_mean"].append(q[0].detach().mean())
        if self.updates % s.policy_frequency == 0:
            frozen = [p.detach() for p in self._critic_params]
            for _ in range(s.policy_steps or s.policy_frequency):
                loss_pi, logp = self.actor_loss(obs, self._noise(obs.shape[0]),
                                                self.log_alpha.detach().exp(), frozen)
                self.actor_optimizer.zero_grad(set_to_none=True)
                loss_pi.backward()
                self.actor_optimizer.step()
                if s.autotune:
                    loss_alpha = self.alpha_loss(logp)
                    self.alpha_optimizer.zero_grad(set_to_none=True)
                    loss_alpha.backward()
                    self.alpha_optimizer.step()
            logs["loss_pi"].append(loss_pi.detach())
            logs["entropy"].append(-logp.detach().mean())

    @torch.no_grad()
    def _update_written(self, obs: torch.Tensor, actions: torch.Tensor, target: torch.Tensor,
                       logs: dict[str, list[torch.Tensor]]) -> None:
        """:meth:`_update_autograd` with the gradients written out
        (:mod:`semdp.algos.kernels.sac_written`): the same floats, no graph."""
        s = self.settings
        hidden = self.critic.hidden
        loss_q, q, grads = sac_written.critic_loss_grads(
            self._critic_params, hidden, obs, actions, target)
        self.critic_optimizer.apply_gradients(grads)
        self.updates += 1
        logs["loss_q"].append(loss_q)
        logs["q_mean"].append(q[0].mean())
        if self.updates % s.policy_frequency == 0:
            for _ in range(s.policy_steps or s.policy_frequency):
                alpha = self.log_alpha.exp()
                loss_pi, logp, grads = sac_written.actor_loss_grads(
                    self.actor, self._critic_params, hidden, obs,
                    self._noise(obs.shape[0]), alpha)
                self.actor_optimizer.apply_gradients(grads)
                if s.autotune:
                    self.alpha_optimizer.apply_gradients(
                        [sac_written.alpha_loss_grad(logp, s.target_entropy)])
            logs["loss_pi"].append(loss_pi)
            logs["entropy"].append(-logp.mean())

    def run(self, n_updates: int, size: int) -> dict[str, Any]:
        """``n_updates`` updates on the first ``size`` replay rows; their logs as floats, the
        temperature after them, the seconds spent and the CPU seconds of this process."""
        start, cpu = time.perf_counter(), time.process_time()
        logs: dict[str, list[torch.Tensor]] = {key: [] for key in LOG_KEYS}
        for _ in range(n_updates):
            self.update(size, logs)
        out: dict[str, Any] = {key: torch.stack(v).tolist() if v else []
                               for key, v in logs.items()}
        out["log_alpha"] = float(self.log_alpha.detach())
        out["busy_s"] = time.perf_counter() - start
        out["cpu_s"] = time.process_time() - cpu
        return out

    # ----------------------------------------------------------------- weights and state
    def actor_vector(self) -> torch.Tensor:
        """The actor's parameters as one flat tensor (what the collecting process acts with)."""
        return nn.utils.parameters_to_vector(self.actor.parameters()).detach()

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimisers, temperature, update count and the generator state."""
        return {
            **networks_state(self),
            "learner_rng": self.generator.get_state(),
            "learner_updates": self.updates,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.actor.load_state_dict(state["actor"])
        self.critic.load_state_dict(state["critic"])
        self.critic_target.load_state_dict(state["critic_target"])
        self.actor_optimizer.load_state_dict(state["actor_optimizer"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        with torch.no_grad():
            self.log_alpha.fill_(state["log_alpha"])
        self.alpha_optimizer.load_state_dict(state["alpha_optimizer"])
        self.generator.set_state(state["learner_rng"])
        self.updates = int(state["learner_updates"])
