"""Soft Actor-Critic with automatic entropy tuning and twin Q (Haarnoja et al. 2018).

CleanRL defaults (docs/training.md, "Algorithms and recorded choices"): 256x256 ReLU, actor lr
3e-4, critic lr 1e-3, tau 0.005, batch 256, 5000 uniformly random steps first, policy delay 2
(the actor and the temperature are then updated twice), target entropy ``-dim(A)``. Time-outs
bootstrap (only ``terminated`` masks the target). SAC optimises reward only -- the cost is
recorded in the replay buffer and logged, which is what the Safety-Embedded MDP's high level
needs (thesis §3.5.1). Works on any gymnasium env with a Box action space; actions are
tanh-squashed to [-1, 1] and scaled to the bounds.

One update (:class:`~semdp.algos.sac.learner.SACLearner`), three loops (``learner``):
``sequential`` -- each vector step is stored, then its updates run, in this process;
``process`` / ``inline`` -- collection proceeds in rounds of ``sync_every`` env steps while the
updates earned by the previous round run, in a learner process on another core (``process``) or
in this process after the round (``inline``, the same numbers); the collector acts with the
weights of the last finished round (docs/semdp.md, "The main job's loop").
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import torch

from semdp.algos.base import Algorithm
from semdp.algos.sac.learner import LOG_KEYS, LearnerSettings, SACLearner
from semdp.algos.sac.learner_host import InlineLearner, ProcessLearner
from semdp.algos.sac.n_step import NStepReturns
from semdp.algos.sac.replay import SharedReplayBuffer
from semdp.common.vector_stepping import merged_step_result
from solvers.workers import HelperError

logger = logging.getLogger(__name__)

#: Values of SAC's ``learner`` argument.
LEARNERS: tuple[str, ...] = ("sequential", "inline", "process")
#: Offset of the learner's generator seed from the run seed (its own random stream).
LEARNER_SEED_OFFSET = 7_777


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
        policy_frequency: actor/temperature updates every this many critic updates.
        policy_steps: actor/temperature updates each time (None: ``policy_frequency``, CleanRL's
            compensation, one actor update per critic update; 1: TD3's delayed actor, half the
            actor's arithmetic at ``policy_frequency=2``).
        alpha: initial (or fixed, without ``autotune``) entropy temperature.
        autotune: learn alpha towards ``target_entropy``.
        target_entropy: defaults to ``-dim(A)``.
        alpha_lr: Adam learning rate of log alpha.
        learner: ``sequential`` (updates after each env step, this process), ``process``
            (updates of the previous round in a learner process while this one collects) or
            ``inline`` (the same rounds, updates in this process; for tests and one core).
        sync_every: env steps (summed over sub-envs) per round of the ``process``/``inline``
            loops: the collector's weights are at most this many steps old.
        learner_threads: torch threads of the learner process.
        n_step: rewards summed per replay row (:mod:`semdp.algos.sac.n_step`; None or 1: one-step
            transitions, SAC as published).
        critic_layer_norm: LayerNorm before every hidden ReLU of the critics
            (:class:`~semdp.algos.sac.twin_q.FusedTwinQ`; DroQ's critic without dropout; None: off).
        gradients: how the learner computes its gradients: ``autograd`` (None; the plain
            path) or ``written`` (:mod:`semdp.algos.kernels.sac_written`: autograd's floats bit for
            bit without its graph, ~20 % less time per update; ReLU networks, no LayerNorm).
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
        policy_steps: int | None = None,
        alpha: float = 1.0,
        autotune: bool = True,
        target_entropy: float | None = None,
        alpha_lr: float = 1e-3,
        learner: str = "sequential",
        sync_every: int = 64,
        learner_threads: int = 1,
        n_step: int | None = None,
        critic_layer_norm: bool | None = None,
        gradients: str | None = None,
    ) -> None:
        super().__init__(envs, eval_envs, seed, steps_per_epoch)
        if learner not in LEARNERS:
            raise ValueError(f"learner must be one of {LEARNERS}, got {learner!r}")
        if sync_every < 1 or learner_threads < 1:
            raise ValueError(f"sync_every and learner_threads must be >= 1, got {sync_every}, "
                             f"{learner_threads}")
        if not 0 <= gamma <= 1:
            raise ValueError(f"gamma must be in [0, 1], got {gamma}")
        if not 0 < tau <= 1:
            raise ValueError(f"tau must be in (0, 1], got {tau}")
        if batch_size < 1 or policy_frequency < 1 or learning_starts < 0:
            raise ValueError(
                "need batch_size >= 1, policy_frequency >= 1, learning_starts >= 0; got "
                f"{batch_size}, {policy_frequency}, {learning_starts}"
            )
        policy_steps = policy_frequency if policy_steps is None else int(policy_steps)
        if policy_steps < 1:
            raise ValueError(f"policy_steps must be >= 1 (or null), got {policy_steps}")
        n_step = 1 if n_step is None else int(n_step)
        if n_step < 1:
            raise ValueError(f"n_step must be >= 1, got {n_step}")
        if updates_per_step <= 0 or alpha <= 0:
            raise ValueError(f"updates_per_step and alpha must be > 0, got {updates_per_step}, "
                             f"{alpha}")
        hidden = tuple(int(h) for h in hidden_sizes)
        self.gamma, self.tau, self.batch_size = gamma, tau, batch_size
        self.learning_starts, self.updates_per_step = learning_starts, updates_per_step
        self.policy_frequency, self.autotune = policy_frequency, autotune
        self.target_entropy = -float(self.act_dim) if target_entropy is None else target_entropy
        self.learner = learner
        self.learner_threads = int(learner_threads)
        self.round_steps = max(1, math.ceil(sync_every / self.num_envs))
        #: Seconds spent on learning as seen by this process (bench: ``semdp-bench semdp``).
        self.timing: dict[str, float] = {"learner_wait_s": 0.0,
                                         "learner_busy_s": 0.0, "learner_cpu_s": 0.0}
        self._update_credit = 0.0
        self._host: InlineLearner | ProcessLearner | None = None
        self.buffer = SharedReplayBuffer(buffer_size, self.obs_dim, self.act_dim,
                                         shared=learner == "process")
        settings = LearnerSettings(
            obs_dim=self.obs_dim, act_dim=self.act_dim, hidden_sizes=hidden,
            actor_lr=actor_lr, critic_lr=critic_lr, gamma=gamma, tau=tau,
            batch_size=batch_size, policy_frequency=policy_frequency,
            policy_steps=policy_steps, alpha=alpha,
            autotune=autotune, target_entropy=self.target_entropy, alpha_lr=alpha_lr,
            seed=self.seed + LEARNER_SEED_OFFSET, n_step=n_step,
            critic_layer_norm=bool(critic_layer_norm), gradients=gradients or "autograd",
        )
        #: n-step rows (None: one-step transitions, stored as they come).
        self._n_step = NStepReturns(n_step, gamma, self.num_envs) if n_step > 1 else None
        self._core = SACLearner(settings, self.buffer.tensors)
        core = self._core
        self.actor, self.critic, self.critic_target = core.actor, core.critic, core.critic_target
        self.actor_optimizer, self.critic_optimizer = core.actor_optimizer, core.critic_optimizer
        self.log_alpha, self.alpha_optimizer = core.log_alpha, core.alpha_optimizer

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

    def train_epoch(self) -> dict[str, float]:
        """``steps_per_epoch`` env steps and ``updates_per_step`` updates per env step: rounds
        of one vector step whose updates follow it (``sequential``) or of ``sync_every`` steps
        whose updates run during the next round (``process``, ``inline``)."""
        logs: dict[str, list[float]] = {k: [] for k in self.extra_columns}
        if self.env_steps + self.steps_per_epoch >= self.learning_starts:
            self._ensure_host()  # a learner process starts while this epoch collects
        if self.learner == "sequential":
            for _ in range(self.n_steps):
                staged, owed = self._collect(1)
                self._store(staged)
                self._ensure_host().start(owed, self.buffer.size)
                self._finish_round(logs)
        else:
            owed, done = 0, 0
            while done < self.n_steps or owed:
                if owed:
                    self._ensure_host().start(owed, self.buffer.size)
                steps = min(self.round_steps, self.n_steps - done)
                staged, owed = self._collect(steps)
                done += steps
                self._finish_round(logs)
                self._store(staged)
        self.epoch += 1
        row = {k: float(np.mean(v)) if v else math.nan for k, v in logs.items()}
        row["alpha"] = self.alpha
        return {**self._pop_episode_stats(), **row}

    def _collect(self, steps: int) -> tuple[list[tuple[np.ndarray, ...]], int]:
        """``steps`` vector steps with the current actor (uniform actions before
        ``learning_starts``); the transitions to store and the updates they earned."""
        staged: list[tuple[np.ndarray, ...]] = []
        owed, rows = 0, 0
        for _ in range(steps):
            if self.env_steps < self.learning_starts:
                unit = torch.rand(self.num_envs, self.act_dim) * 2 - 1
            else:
                with torch.inference_mode():
                    unit, _ = self.actor(torch.as_tensor(self._obs, dtype=torch.float32))
            next_obs, rewards, term, trunc, infos = self.envs.step(self.to_env_action(unit))
            ended = np.logical_or(term, trunc)
            result = merged_step_result(next_obs, rewards, term, trunc, infos)
            costs, final_obs = result.costs, result.final_observations()
            step = (self._obs, unit.numpy(), rewards, costs, self._flat_obs(final_obs),
                    term.astype(np.float32))
            if self._n_step is not None:
                step = self._n_step.push(*step, ended)
            staged.append(step)
            rows += len(step[2])
            self._track(rewards, costs, ended)
            self._obs = self._flat_obs(next_obs)
            self.env_steps += self.num_envs
            stored = min(self.buffer.size + rows, self.buffer.capacity)
            if self.env_steps >= self.learning_starts and stored >= self.batch_size:
                self._update_credit += self.updates_per_step * self.num_envs
                while self._update_credit >= 1.0:
                    self._update_credit -= 1.0
                    owed += 1
        return staged, owed

    def _store(self, staged: list[tuple[np.ndarray, ...]]) -> None:
        if staged:
            self.buffer.add_batch(*(np.concatenate(part) for part in zip(*staged, strict=True)))

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimisers, temperature, the learner's generator and the replay buffer."""
        learner = self._host.state_dict() if self._host is not None else self._core.state_dict()
        state = {**super().state_dict(), **learner, "buffer": self.buffer.state_dict(),
                 "update_credit": self._update_credit}
        if self._n_step is not None:
            state["n_step"] = self._n_step.state_dict()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self._core.load_state_dict(state)
        if self._host is not None:
            self._host.load_state_dict(state)
        self.buffer.load_state_dict(state["buffer"])
        self._update_credit = state["update_credit"]
        if self._n_step is not None:
            if state.get("envs") is None:  # the episodes in progress were restarted
                self._n_step.clear()
            else:
                self._n_step.load_state_dict(state["n_step"])

    # ----------------------------------------------------------------- rounds (learner process)
    def _ensure_host(self) -> InlineLearner | ProcessLearner:
        if self._host is None:
            self._host = (ProcessLearner(self._core, self.buffer, self.learner_threads)
                          if self.learner == "process" else InlineLearner(self._core))
        return self._host

    def _finish_round(self, logs: dict[str, list[float]]) -> None:
        """Wait for the learner's round; its logs, temperature and actor weights."""
        host = self._host
        if host is None:  # no learner yet: nothing was sent
            return
        start = time.perf_counter()
        out = host.wait()
        self.timing["learner_wait_s"] += time.perf_counter() - start
        if out is None:
            return
        self.timing["learner_busy_s"] += out["busy_s"]
        self.timing["learner_cpu_s"] += out["cpu_s"]
        for key in LOG_KEYS:
            logs[key].extend(out[key])
        with torch.no_grad():
            self.log_alpha.fill_(out["log_alpha"])
        host.pull_actor(self.actor)

    def learn(self, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """:meth:`Algorithm.learn`; a learner process lives only as long as this call (on an
        error or Ctrl-C it is terminated, else its state is copied back first)."""
        finished = False
        try:
            metrics = super().learn(*args, **kwargs)
            finished = True
            return metrics
        finally:
            self.close(keep_state=finished)

    def close(self, keep_state: bool = True) -> None:
        """Stop the learner process, if any (its state copied back with ``keep_state``)."""
        host, self._host = self._host, None
        if host is not None:
            host.close(keep_state=keep_state)

    def close_helpers(self) -> None:
        """Stop the learner process when the training loop ends (also on errors and Ctrl-C,
        where a failure to copy its state back is only logged: the last checkpoint has it)."""
        try:
            self.close(keep_state=True)
        except HelperError as exc:
            logger.warning("learner process state not copied back: %s", exc)
