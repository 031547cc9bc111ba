"""Soft Actor-Critic with automatic entropy tuning and twin Q (Haarnoja et al. 2018).

CleanRL defaults (research/saferl_anchors.md §5.2): 256x256 ReLU, actor lr 3e-4, critic lr 1e-3,
tau 0.005, batch 256, 5000 uniformly random steps first, policy delay 2 (the actor and the
temperature are then updated twice), target entropy ``-dim(A)``. Time-outs bootstrap (only
``terminated`` masks the target). SAC optimises reward only -- the cost is recorded in the replay
buffer and logged, which is what the Safety-Embedded MDP's high level needs (SPEC §4.2).
Works on any gymnasium env with a Box action space; actions are tanh-squashed to [-1, 1] and
scaled to the bounds.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import torch

from semdp.algos.base import Algorithm
from semdp.common.buffers import ReplayBuffer
from semdp.common.networks import SquashedGaussianActor, TwinQCritic
from semdp.envs import split_step_infos


class SAC(Algorithm):
    """SAC for continuous actions.

    Args:
        envs, eval_envs, seed, steps_per_epoch: see :class:`~semdp.algos.base.Algorithm`.
        hidden_sizes: MLP sizes of actor and critics.
        actor_lr, critic_lr: Adam learning rates.
        gamma: discount.
        tau: Polyak factor of the target critics.
        batch_size: minibatch size.
        buffer_size: replay capacity (transitions).
        learning_starts: env steps of uniformly random actions before learning.
        updates_per_step: gradient updates per env step (summed over sub-envs).
        policy_frequency: actor/temperature update every this many critic updates (done that
            many times to compensate).
        alpha: initial (or fixed, without ``autotune``) entropy temperature.
        autotune: learn alpha towards ``target_entropy``.
        target_entropy: defaults to ``-dim(A)``.
        alpha_lr: Adam learning rate of log alpha.
    """

    extra_columns = ("loss_q", "loss_pi", "alpha", "q_mean", "entropy")

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        steps_per_epoch: int = 2000,
        hidden_sizes: tuple[int, ...] = (256, 256),
        actor_lr: float = 3e-4,
        critic_lr: float = 1e-3,
        gamma: float = 0.99,
        tau: float = 0.005,
        batch_size: int = 256,
        buffer_size: int = 1_000_000,
        learning_starts: int = 5000,
        updates_per_step: float = 1.0,
        policy_frequency: int = 2,
        alpha: float = 1.0,
        autotune: bool = True,
        target_entropy: float | None = None,
        alpha_lr: float = 1e-3,
    ) -> None:
        super().__init__(envs, eval_envs, seed, steps_per_epoch)
        if not 0 <= gamma <= 1:
            raise ValueError(f"gamma must be in [0, 1], got {gamma}")
        if not 0 < tau <= 1:
            raise ValueError(f"tau must be in (0, 1], got {tau}")
        if batch_size < 1 or policy_frequency < 1 or learning_starts < 0:
            raise ValueError(
                "need batch_size >= 1, policy_frequency >= 1, learning_starts >= 0; got "
                f"{batch_size}, {policy_frequency}, {learning_starts}"
            )
        if updates_per_step <= 0 or alpha <= 0:
            raise ValueError(f"updates_per_step and alpha must be > 0, got {updates_per_step}, "
                             f"{alpha}")
        hidden = tuple(int(h) for h in hidden_sizes)
        self.gamma, self.tau, self.batch_size = gamma, tau, batch_size
        self.learning_starts, self.updates_per_step = learning_starts, updates_per_step
        self.policy_frequency, self.autotune = policy_frequency, autotune
        self.actor = SquashedGaussianActor(self.obs_dim, self.act_dim, hidden)
        self.critic = TwinQCritic(self.obs_dim, self.act_dim, hidden)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=actor_lr)
        self.critic_optimizer = torch.optim.Adam(self.critic.parameters(), lr=critic_lr)
        self.target_entropy = -float(self.act_dim) if target_entropy is None else target_entropy
        self.log_alpha = torch.tensor(math.log(alpha), requires_grad=True)
        self.alpha_optimizer = torch.optim.Adam([self.log_alpha], lr=alpha_lr)
        self.buffer = ReplayBuffer(buffer_size, self.obs_dim, self.act_dim)
        self._updates = 0
        self._update_credit = 0.0

    @property
    def alpha(self) -> float:
        """Current entropy temperature."""
        return self.log_alpha.detach().exp().item()

    def predict(self, obs: npt.ArrayLike, deterministic: bool = True) -> npt.NDArray[Any]:
        """tanh(mean) (or a sample), scaled to the env bounds."""
        with torch.no_grad():
            a, _ = self.actor(torch.as_tensor(self._flat_obs(obs), dtype=torch.float32),
                              deterministic)
        return self.to_env_action(a.numpy())

    def _update(self) -> dict[str, float]:
        batch = self.buffer.sample(self.batch_size)
        alpha = self.log_alpha.exp().detach()
        with torch.no_grad():
            next_a, next_logp = self.actor(batch.next_obs)
            q1_t, q2_t = self.critic_target(batch.next_obs, next_a)
            soft_v = torch.min(q1_t, q2_t) - alpha * next_logp
            target = batch.rewards + self.gamma * (1.0 - batch.terminated) * soft_v
        q1, q2 = self.critic(batch.obs, batch.actions)
        loss_q = ((q1 - target) ** 2).mean() + ((q2 - target) ** 2).mean()
        self.critic_optimizer.zero_grad()
        loss_q.backward()
        self.critic_optimizer.step()
        self._updates += 1
        out = {"loss_q": loss_q.item(), "q_mean": q1.mean().item()}
        if self._updates % self.policy_frequency == 0:
            for _ in range(self.policy_frequency):
                a, logp = self.actor(batch.obs)
                q1_pi, q2_pi = self.critic(batch.obs, a)
                loss_pi = (self.log_alpha.exp().detach() * logp - torch.min(q1_pi, q2_pi)).mean()
                self.actor_optimizer.zero_grad()
                loss_pi.backward()
                self.actor_optimizer.step()
                out.update(loss_pi=loss_pi.item(), entropy=-logp.mean().item())
                if self.autotune:
                    loss_alpha = -(self.log_alpha * (logp.detach() + self.target_entropy)).mean()
                    self.alpha_optimizer.zero_grad()
                    loss_alpha.backward()
                    self.alpha_optimizer.step()
        with torch.no_grad():
            for p, p_t in zip(self.critic.parameters(), self.critic_target.parameters(),
                              strict=True):
                p_t.mul_(1 - self.tau).add_(self.tau * p)
        return out

    def train_epoch(self) -> dict[str, float]:
        """``steps_per_epoch`` env steps, each followed by ``updates_per_step`` updates."""
        logs: dict[str, list[float]] = {k: [] for k in self.extra_columns}
        for _ in range(self.n_steps):
            if self.env_steps < self.learning_starts:
                unit = torch.rand(self.num_envs, self.act_dim) * 2 - 1
            else:
                with torch.no_grad():
                    unit, _ = self.actor(torch.as_tensor(self._obs, dtype=torch.float32))
            next_obs, rewards, term, trunc, infos = self.envs.step(self.to_env_action(unit))
            ended = np.logical_or(term, trunc)
            costs, final_obs = split_step_infos(next_obs, infos, ended)
            self.buffer.add_batch(self._obs, unit.numpy(), rewards, costs,
                                  self._flat_obs(final_obs), term.astype(np.float32))
            self._track(rewards, costs, ended)
            self._obs = self._flat_obs(next_obs)
            self.env_steps += self.num_envs
            if self.env_steps >= self.learning_starts and self.buffer.size >= self.batch_size:
                self._update_credit += self.updates_per_step * self.num_envs
                while self._update_credit >= 1.0:
                    self._update_credit -= 1.0
                    for k, v in self._update().items():
                        logs[k].append(v)
        self.epoch += 1
        row = {k: float(np.mean(v)) if v else math.nan for k, v in logs.items()}
        row["alpha"] = self.alpha
        return {**self._pop_episode_stats(), **row}

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimisers, temperature and the replay buffer."""
        return {
            **super().state_dict(),
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "critic_target": self.critic_target.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "log_alpha": float(self.log_alpha.detach()),
            "alpha_optimizer": self.alpha_optimizer.state_dict(),
            "buffer": self.buffer.state_dict(),
            "updates": (self._updates, self._update_credit),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self.actor.load_state_dict(state["actor"])
        self.critic.load_state_dict(state["critic"])
        self.critic_target.load_state_dict(state["critic_target"])
        self.actor_optimizer.load_state_dict(state["actor_optimizer"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        with torch.no_grad():
            self.log_alpha.fill_(state["log_alpha"])
        self.alpha_optimizer.load_state_dict(state["alpha_optimizer"])
        self.buffer.load_state_dict(state["buffer"])
        self._updates, self._update_credit = state["updates"]
