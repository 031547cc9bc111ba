"""The on-policy base of PPO, TRPO and their constrained variants (thesis Eqs. 2.4-2.7): a
Gaussian actor, a reward critic and a cost critic.

An epoch, in the order the subclasses' ``train_epoch`` runs it:

1. **rollout** -- :meth:`OnPolicyAlgorithm.collect_rollout`: the sampling noise of the epoch is
   drawn, the collector acts and steps the envs (:mod:`semdp.algos.rollout`), then
   :meth:`~OnPolicyAlgorithm.value_rollout` values every step with the critics and bootstraps
   time-outs with V(true final observation);
2. (the multiplier step of the constrained variants, :mod:`semdp.algos.lagrangian`);
3. **GAE** -- :meth:`~OnPolicyAlgorithm.compute_batch` (:mod:`semdp.algos.gae`);
4. **actor** -- the subclass (PPO's clipped passes, TRPO's natural-gradient step);
5. **critics** -- :meth:`~OnPolicyAlgorithm.update_critics`: minibatch regression of V_r and V_c
   on their GAE returns (:mod:`semdp.algos.critic_regression`).

Two seams take speed-ups handed in by the caller, and this file imports none of them: the
update ``kernel`` (:class:`Autograd`, the plain path, unless one is given) and the ``runners``,
a factory of the rollout collector and the critic runner (this process unless one is given).
:mod:`semdp.algos.speedups` builds both from the config keys ``algo.gradients``,
``algo.vectorization`` and ``algo.parallel_critics`` (:func:`semdp.build.build_algorithm`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import torch
from torch import nn

from semdp.algos import critic_regression
from semdp.algos.base import Algorithm
from semdp.algos.critic_regression import CriticTargets
from semdp.algos.gae import RolloutBatch, RolloutBuffer
from semdp.algos.rollout import LocalCollector, RolloutPart, noise_for
from semdp.common.networks import GaussianActor, ValueCritic
from semdp.common.normalization import RunningNormalizer
from semdp.common.optim import FlatAdam

#: The ``runners`` seam: (envs, policy, owner, regress, local critics) -> (collector, critic
#: runner); ``policy`` is (actor, normaliser, action scaling), ``owner`` the algorithm.
Runners = Callable[..., tuple[Any, Any]]


class Autograd:
    """The plain update kernel: no written-out derivatives, so every caller takes its own
    autograd path (the interface of :class:`~semdp.algos.kernels.written.WrittenDerivatives`)."""

    name = "autograd"

    def critics(self, critic_r: nn.Module, critic_c: nn.Module, optimizer: Any) -> None:
        """No stacked regression."""

    def ppo_step(self, actor: nn.Module, optimizer: Any) -> None:
        """No written PPO step."""

    def fisher(self, actor: nn.Module, obs: torch.Tensor, damping: float) -> None:
        """No written Fisher-vector product."""

    def check_critics(self, *args: Any) -> None:
        """Nothing to check: the critics' loss runs as defined."""

    def check_ppo(self, *args: Any) -> None:
        """Nothing to check: PPO's loss runs as defined."""

    def check_fisher(self, *args: Any) -> None:
        """Nothing to check: the Fisher-vector product runs as defined."""


class LocalCritics:
    """The plain critic runner: the critics regress in this process after the actor update."""

    in_helper = False

    def __init__(self, update: Callable[[RolloutBatch], dict[str, float]]) -> None:
        self.update = update

    def start(self, batch: RolloutBatch, skip: int) -> None:
        """Nothing runs during the actor update."""

    def finish(self, batch: RolloutBatch, job: None, drawn: int) -> dict[str, float]:
        """Regress the critics now."""
        return self.update(batch)

    def stop(self) -> None:
        """No helper."""


class OnPolicyAlgorithm(Algorithm):
    """Rollouts with a Gaussian actor, reward critic and cost critic (shared by PPO and TRPO).

    Observation normalisation: the running statistics are updated once per epoch, after the
    rollout, so every sample of a batch was normalised the same way as the policy saw it.

    Args:
        envs, eval_envs, seed, steps_per_epoch: see :class:`~semdp.algos.base.Algorithm`.
        hidden_sizes: MLP sizes of actor and critics.
        activation: hidden activation.
        log_std_init: initial log standard deviation of the policy.
        gamma, gae_lambda: reward discount and GAE lambda.
        gamma_c, gae_lambda_c: cost discount and GAE lambda.
        critic_lr: Adam learning rate of both critics.
        critic_iters: passes over the batch for the critics per epoch.
        critic_minibatches: minibatches per critic pass.
        critic_l2: L2 regularisation of critic weights (OmniSafe ``critic_norm_coef``).
        max_grad_norm: gradient-norm clip (``None`` = off).
        obs_normalize: running observation normalisation on/off.
        obs_clip: clip of normalised observations.
        kernel: the update kernel; None: :class:`Autograd` (the losses as defined here and in
            the algorithm's file). A kernel with derivatives written out
            (:mod:`semdp.algos.speedups`, ``algo.gradients=written``) is checked at construction
            against those losses.
        runners: the factory of the rollout collector and the critic runner (:data:`Runners`);
            None: the envs step and the critics regress in this process.
    """

    #: ``rollout_helper``/``critic_helper``: 1 where the epoch used that helper.
    base_columns: tuple[str, ...] = ("loss_v", "loss_vc", "entropy", "kl", "rollout_helper",
                                     "critic_helper")

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        steps_per_epoch: int = 20_000,
        hidden_sizes: tuple[int, ...] = (64, 64),
        activation: str = "tanh",
        log_std_init: float = 0.0,
        gamma: float = 0.99,
        gae_lambda: float = 0.95,
        gamma_c: float = 0.99,
        gae_lambda_c: float = 0.95,
        critic_lr: float = 3e-4,
        critic_iters: int = 10,
        critic_minibatches: int = 32,
        critic_l2: float = 0.001,
        max_grad_norm: float | None = 0.5,
        obs_normalize: bool = True,
        obs_clip: float = 5.0,
        kernel: Any = None,
        runners: Runners | None = None,
    ) -> None:
        super().__init__(envs, eval_envs, seed, steps_per_epoch)
        for name, v in (("critic_iters", critic_iters), ("critic_minibatches", critic_minibatches)):
            if v < 1:
                raise ValueError(f"{name} must be >= 1, got {v}")
        self.gamma, self.gae_lambda = gamma, gae_lambda
        self.gamma_c, self.gae_lambda_c = gamma_c, gae_lambda_c
        self.critic_iters, self.critic_minibatches = critic_iters, critic_minibatches
        self.critic_l2, self.max_grad_norm = critic_l2, max_grad_norm
        hidden = tuple(int(h) for h in hidden_sizes)
        self.actor = GaussianActor(self.obs_dim, self.act_dim, hidden, activation, log_std_init)
        self.critic_r = ValueCritic(self.obs_dim, hidden, activation)
        self.critic_c = ValueCritic(self.obs_dim, hidden, activation)
        self.critic_optimizer = FlatAdam(
            [*self.critic_r.parameters(), *self.critic_c.parameters()], lr=critic_lr
        )
        self.normalizer = RunningNormalizer((self.obs_dim,), clip=obs_clip, enabled=obs_normalize)
        self.buffer = RolloutBuffer(self.n_steps, self.num_envs, self.obs_dim, self.act_dim)
        self.last_ep_cost: float | None = None
        self.last_ep_length: float | None = None
        # the seams (semdp.algos.speedups): update kernel; rollout collector and critic runner
        self.kernel: Any = Autograd() if kernel is None else kernel
        self.kernel.check_critics(self.critic_r, self.critic_c, self.critic_optimizer, critic_l2,
                                  critic_regression.critic_loss, self.obs_dim)
        self.regress = functools.partial(critic_regression.regress_critics, kernel=self.kernel)
        policy = (self.actor, self.normalizer, self.to_env_action)
        self.collector: Any = LocalCollector(*policy)
        self.critics: Any = LocalCritics(self.update_critics)
        if runners is not None:
            self.collector, self.critics = runners(envs, policy, self, self.regress, self.critics)

    @property
    def envs_in_helper(self) -> bool:
        """Whether the envs step with a helper this epoch (the choice of ``auto``)."""
        return bool(self.collector.in_helper)

    @property
    def critics_in_helper(self) -> bool:
        """Whether the critics regress in a helper in this update (the choice of ``auto``)."""
        return bool(self.critics.in_helper)

    # ----------------------------------------------------------------- acting
    def _tensor(self, obs: npt.ArrayLike) -> torch.Tensor:
        return torch.as_tensor(self.normalizer(self._flat_obs(obs)))

    def predict(self, obs: npt.ArrayLike, deterministic: bool = True) -> npt.NDArray[Any]:
        """Mean (or sampled) action, clipped and scaled to the env bounds."""
        with torch.inference_mode():
            x = self._tensor(obs)
            a = self.actor.mean(x) if deterministic else self.actor.distribution(x).sample()
        return self.to_env_action(a.numpy())

    # ----------------------------------------------------------------- 1. rollout
    def collect_rollout(self) -> dict[str, float]:
        """Fill the rollout buffer with ``n_steps`` vector steps; return episode statistics."""
        noise = noise_for(self.n_steps, self.num_envs, self.act_dim)
        part = self.collector.collect(self.envs, self._obs, noise, self.timer.seconds)
        stats = self.value_rollout(part)
        stats["rollout_helper"] = float(self.collector.used_helper)
        return stats

    def value_rollout(self, part: RolloutPart) -> dict[str, float]:
        """Store ``part`` in the buffer, value it with the critics, track the episodes."""
        perf = time.perf_counter
        seconds = self.timer.seconds
        start = perf()
        buf = self.buffer
        ended = np.logical_or(part.terminated, part.truncated)
        buf.obs[...], buf.actions[...], buf.log_probs[...] = part.obs, part.actions, \
            part.log_probs
        buf.rewards[...], buf.costs[...] = part.rewards, part.costs
        buf.terminated[...], buf.episode_end[...] = part.terminated, ended
        buf.pos = self.n_steps
        boot_r = np.zeros((self.n_steps, self.num_envs))
        boot_c = np.zeros((self.n_steps, self.num_envs))
        valuing = 0.0
        for t in range(self.n_steps):
            t0 = perf()
            with torch.inference_mode():  # the per-step batches the rollout had
                obs_t = torch.as_tensor(part.obs[t])
                buf.values_r[t] = self.critic_r(obs_t).numpy()
                buf.values_c[t] = self.critic_c(obs_t).numpy()
                timed_out = np.logical_and(ended[t], np.logical_not(part.terminated[t]))
                if timed_out.any():  # bootstrap time-outs with V(true final observation)
                    final = np.stack([part.final_obs[t, i] for i in np.flatnonzero(timed_out)])
                    fo = self._tensor(final)
                    boot_r[t, timed_out] = self.critic_r(fo).numpy()
                    boot_c[t, timed_out] = self.critic_c(fo).numpy()
            valuing += perf() - t0
            self._track(part.rewards[t], part.costs[t], ended[t])
        assert part.last_obs is not None
        self._obs = part.last_obs
        with torch.inference_mode():  # bootstrap the cut at the end of the rollout
            last = self._tensor(self._obs)
            last_r, last_c = self.critic_r(last).numpy(), self.critic_c(last).numpy()
        buf.next_values_r[:-1], buf.next_values_r[-1] = buf.values_r[1:], last_r
        buf.next_values_c[:-1], buf.next_values_c[-1] = buf.values_c[1:], last_c
        episode_end = buf.episode_end.astype(bool)
        buf.next_values_r[episode_end] = boot_r[episode_end]
        buf.next_values_c[episode_end] = boot_c[episode_end]
        self.normalizer.update(part.raw_obs.reshape(-1, self.obs_dim))
        self.env_steps += self.steps_per_epoch
        stats = self._pop_episode_stats()
        if stats["episodes"]:
            self.last_ep_cost, self.last_ep_length = stats["ep_cost"], stats["ep_length"]
        seconds["policy"] += valuing
        seconds["storage"] += perf() - start - valuing
        return stats

    # ----------------------------------------------------------------- 3. GAE
    def compute_batch(self) -> RolloutBatch:
        """GAE for reward and cost over the filled buffer."""
        with self.timer.phase("storage"):
            return self.buffer.compute(self.gamma, self.gae_lambda, self.gamma_c,
                                       self.gae_lambda_c)

    def estimated_episode_cost(self) -> float:
        """J_c for the multiplier: mean cost of the episodes finished in the latest epochs.

        Falls back to the per-step cost of the current rollout times its length when no
        episode has finished yet.
        """
        if self.last_ep_cost is not None:
            return self.last_ep_cost
        return float(self.buffer.costs.mean() * self.n_steps)

    # ----------------------------------------------------------------- 5. critics
    def critic_minibatch(self, n: int) -> int:
        """Minibatch size of the critic regression on ``n`` samples."""
        return max(1, n // self.critic_minibatches)

    def update_critics(self, batch: RolloutBatch) -> dict[str, float]:
        """Regress V_r and V_c on their GAE returns here, one permutation per pass from
        torch's global generator."""
        n = batch.obs.shape[0]
        perms = [torch.randperm(n) for _ in range(self.critic_iters)]
        losses = self.regress(self.critic_r, self.critic_c, self.critic_optimizer,
                              CriticTargets(batch.obs, batch.ret_r, batch.ret_c), perms,
                              self.critic_minibatch(n), self.critic_l2, self.max_grad_norm)
        assert losses is not None  # no stop condition here
        return {"loss_v": losses[0], "loss_vc": losses[1], "critic_helper": 0.0}

    # ----------------------------------------------------------------- helpers and state
    def env_snapshot(self) -> Any:
        """The training env for a checkpoint (with a rollout helper, its live sub-envs)."""
        return self.collector.snapshot(self.envs)

    def replace_envs(self, envs: gym.vector.VectorEnv) -> None:
        """Continue with ``envs``; a helper rolling out the old ones is stopped."""
        self.collector.stop(fetch=False)
        super().replace_envs(envs)

    def close_helpers(self) -> None:
        """Stop the helpers; the rollout helper's live envs become :attr:`envs` again."""
        self.collector.stop(fetch=True)
        self.critics.stop()

    def policy_state(self) -> dict[str, Any]:
        """The actor and the observation normaliser's statistics."""
        return {**super().policy_state(), "normalizer": self.normalizer.state_dict()}

    def load_policy_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`policy_state`."""
        super().load_policy_state(state)
        self.normalizer.load_state_dict(state["normalizer"])

    def state_dict(self) -> dict[str, Any]:
        """Base state plus networks, critic optimiser and normaliser."""
        state = super().state_dict()
        state.update(
            actor=self.actor.state_dict(),
            critic_r=self.critic_r.state_dict(),
            critic_c=self.critic_c.state_dict(),
            critic_optimizer=self.critic_optimizer.state_dict(),
            normalizer=self.normalizer.state_dict(),
            last_ep=(self.last_ep_cost, self.last_ep_length),
        )
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (a helper rolling out the previous envs is stopped)."""
        self.collector.stop(fetch=False)
        super().load_state_dict(state)
        self.actor.load_state_dict(state["actor"])
        self.critic_r.load_state_dict(state["critic_r"])
        self.critic_c.load_state_dict(state["critic_c"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        self.normalizer.load_state_dict(state["normalizer"])
        self.last_ep_cost, self.last_ep_length = state["last_ep"]
