"""On-policy rollouts with a Gaussian actor, a reward critic and a cost critic (PPO and TRPO
families; semdp/README.md, "Algorithms and recorded choices").

Two optional helper processes use a second core without changing a single number (same seed,
same ``progress.csv``; semdp/README.md, "Throughput"):

* ``vectorization="async"``: a forked helper rolls out 3/5 of the training sub-envs for the
  whole epoch (:class:`~semdp.algos.rollout_helper.RolloutHelper`) while the trainer rolls out
  the others; the critics value the merged rollout afterwards (:mod:`semdp.algos.rollout`);
* ``parallel_critics=True``: the critics regress in a forked helper
  (:class:`~semdp.common.critic_worker.CriticWorker`) while the actor updates; the helper gets
  the permutations the trainer's generator would have drawn for them.

``"auto"`` (the default of both) uses a helper where the platform can fork and two CPUs are
available, and only while it is faster: the first rollout and update run in the trainer, the
second with the helpers, then :class:`~semdp.common.option_probe.FasterOption` keeps the faster
way and measures the other again when the load changes (on a machine whose cores other jobs
keep busy, the helpers only add pipe traffic). Envs whose vector step took less than
:data:`ASYNC_MIN_STEP_S` in the first rollout stay in the trainer (the pipe costs more), and so
do sub-envs with a wrapper of their own (its state, e.g. the SEMDP wrapper's timings, is read
from the trainer's copy). Switching changes no number.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import torch

from semdp.algos.base import Algorithm
from semdp.algos.rollout import RolloutPart, noise_for, roll_part
from semdp.algos.rollout_helper import RolloutHelper
from semdp.common.buffers import RolloutBatch, RolloutBuffer
from semdp.common.critic_regression import CriticTargets, regress_critics
from semdp.common.critic_worker import CriticWorker
from semdp.common.networks import GaussianActor, ValueCritic
from semdp.common.normalization import RunningNormalizer
from semdp.common.optim import FlatAdam
from semdp.common.option_probe import FasterOption, idle_core
from semdp.common.vector_stepping import VectorStepper, stepper_for
from solvers.workers import fork_available

logger = logging.getLogger(__name__)

VECTORIZATION_MODES: tuple[str, ...] = ("sync", "async", "auto")
#: ``gradients=``: derivatives written out where the networks allow it, or autograd throughout.
GRADIENTS: tuple[str, ...] = ("written", "autograd")
#: ``vectorization="auto"``: seconds per vector step of the envs (first rollout, in this
#: process) from which they move to the helper.
ASYNC_MIN_STEP_S = 2e-4
#: Fraction of the sub-envs the trainer rolls out itself with ``async`` (it also values the
#: merged rollout, so it takes a little less than half).
TRAINER_SHARE: tuple[int, int] = (2, 5)
#: Modules whose wrappers keep no state the trainer reads (``auto`` may fork the envs).
_PLAIN_WRAPPER_MODULES: tuple[str, ...] = ("gymnasium.", "semdp.envs")


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - platforms without sched_getaffinity
        return os.cpu_count() or 1


def _plain_sub_envs(envs: gym.vector.VectorEnv) -> bool:
    """A plain ``SyncVectorEnv`` (not a subclass with a ``step`` of its own) whose sub-envs'
    wrappers are all gymnasium's or the cost checks of :mod:`semdp.envs`."""
    if type(envs) is not gym.vector.SyncVectorEnv:
        return False
    for env in envs.envs:
        while isinstance(env, gym.Wrapper):
            if not type(env).__module__.startswith(_PLAIN_WRAPPER_MODULES):
                return False
            env = env.env
    return True


@dataclass(frozen=True)
class _CriticJob:
    """A critic regression running in the helper, on the permutations after ``skip`` draws."""

    skip: int


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
        vectorization: ``"sync"`` (training envs step in this process), ``"async"`` (in a
            forked helper) or ``"auto"`` (see the module docstring).
        parallel_critics: regress the critics in a forked helper during the actor update
            (``True``/``False``/``"auto"``).
        gradients: ``"written"`` (the default MLPs' derivatives written out: both critics'
            regression as one stacked network, :mod:`semdp.common.stacked_critics`; PPO's
            clipped-surrogate step, :mod:`semdp.common.ppo_actor_step`; TRPO's and CPO's
            Fisher-vector product, :mod:`semdp.common.gaussian_fisher`) or ``"autograd"``
            (the same quantities through autograd, ~2-3x slower; the numbers differ in the
            last bits, the learning curves within noise).
    """

    #: ``rollout_helper``/``critic_helper``: 1 where the epoch used that helper (the choice of
    #: ``auto`` recorded).
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
        vectorization: str = "auto",
        parallel_critics: bool | str = "auto",
        gradients: str = "written",
    ) -> None:
        super().__init__(envs, eval_envs, seed, steps_per_epoch)
        if gradients not in GRADIENTS:
            raise ValueError(f"gradients must be one of {list(GRADIENTS)}, got {gradients!r}")
        #: ``gradients="autograd"``: no written-out derivatives.
        self.autograd_only = gradients == "autograd"
        for name, v in (("critic_iters", critic_iters), ("critic_minibatches", critic_minibatches)):
            if v < 1:
                raise ValueError(f"{name} must be >= 1, got {v}")
        if vectorization not in VECTORIZATION_MODES:
            raise ValueError(f"vectorization must be one of {list(VECTORIZATION_MODES)}, "
                             f"got {vectorization!r}")
        if parallel_critics not in (True, False, "auto"):
            raise ValueError(f"parallel_critics must be true, false or 'auto', "
                             f"got {parallel_critics!r}")
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
        helpers = fork_available() and _cpus() >= 2
        if "async" in (vectorization, parallel_critics) or parallel_critics is True:
            if not fork_available():
                raise ValueError("helper processes need the 'fork' start method")
        if vectorization == "async" and type(envs) is not gym.vector.SyncVectorEnv:
            raise ValueError(f"vectorization='async' steps the sub-envs of a gymnasium "
                             f"SyncVectorEnv, got {type(envs).__name__}")
        self.vectorization, self.parallel_critics = vectorization, parallel_critics
        #: Whether the envs step with a helper (per rollout) and the critics regress in one
        #: (per update): fixed by ``"sync"``/``"async"``/``True``/``False``, probed by ``auto``.
        # with a core idle now, the helpers are used from the first epoch (option_probe)
        first = helpers and "auto" in (vectorization, parallel_critics) and idle_core()
        self._env_choice = FasterOption(helpers and _plain_sub_envs(envs), first=first)
        self._critic_choice = FasterOption(helpers, first=first)
        self.envs_in_helper = vectorization == "async"
        self.critics_in_helper = parallel_critics is True
        self._update_start = 0.0
        self._rollout_helper: RolloutHelper | None = None
        self._critic_worker: CriticWorker | None = None

    # ----------------------------------------------------------------- acting
    def _tensor(self, obs: npt.ArrayLike) -> torch.Tensor:
        return torch.as_tensor(self.normalizer(self._flat_obs(obs)))

    def predict(self, obs: npt.ArrayLike, deterministic: bool = True) -> npt.NDArray[Any]:
        """Mean (or sampled) action, clipped and scaled to the env bounds."""
        with torch.inference_mode():
            x = self._tensor(obs)
            a = self.actor.mean(x) if deterministic else self.actor.distribution(x).sample()
        return self.to_env_action(a.numpy())

    def _helper_for_rollout(self) -> RolloutHelper | None:
        """The rollout helper of this epoch (``None`` when the trainer rolls out every env)."""
        if self.vectorization == "auto":
            self.envs_in_helper = self._env_choice.choose()
        local = max(1, (self.num_envs * TRAINER_SHARE[0]) // TRAINER_SHARE[1])
        if not self.envs_in_helper or local >= self.num_envs:
            self._stop_rollout_helper(fetch=True)
            return None
        if self._rollout_helper is None:
            self._rollout_helper = RolloutHelper(
                self.envs, range(local, self.num_envs), self.actor, self.normalizer,
                self.to_env_action)
        return self._rollout_helper

    def collect_rollout(self) -> dict[str, float]:
        """Fill the rollout buffer with ``n_steps`` vector steps; return episode statistics.

        The sampling noise of the epoch is drawn first; the sub-envs are rolled out (the last
        ones by the helper, if it is used: :mod:`semdp.algos.rollout`), then the critics value
        every step and time-outs are bootstrapped with V(true final observation), step by step
        as the rollout went.
        """
        perf = time.perf_counter
        seconds = self.timer.seconds
        rollout_start = perf()
        helper = self._helper_for_rollout()
        noise = noise_for(self.n_steps, self.num_envs, self.act_dim)
        local = helper.rows.start if helper is not None else self.num_envs
        if helper is not None:
            helper.start(self.actor, self.normalizer, noise[:, local:], self._obs[local:])
            stepper = VectorStepper(self.envs, range(local))
        else:
            stepper = stepper_for(self.envs)
        part = roll_part(self.actor, self.normalizer, self.to_env_action, stepper,
                         range(local), self.num_envs, noise[:, :local], self._obs[:local])
        seconds["policy"] += part.policy_s
        seconds["simulation"] += part.simulation_s
        # this process's vector step, scaled to all the sub-envs
        step_s = part.simulation_s * self.num_envs / max(local, 1) / self.n_steps
        if helper is not None:
            wait = perf()
            remote = helper.result()
            seconds["simulation"] += perf() - wait
            seconds["simulation_worker"] += remote.simulation_s
            part = RolloutPart.concatenate(part, remote)
        if step_s < ASYNC_MIN_STEP_S:  # cheaper than the pipe to a helper: the envs stay here
            self._env_choice.disallow()
        stats = self._value_rollout(part)
        stats["rollout_helper"] = float(helper is not None)
        self._env_choice.record(self.envs_in_helper, perf() - rollout_start)
        return stats

    def _value_rollout(self, part: RolloutPart) -> dict[str, float]:
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

    # ----------------------------------------------------------------- critics
    def _critic_minibatch(self, n: int) -> int:
        return max(1, n // self.critic_minibatches)

    def update_critics(self, batch: RolloutBatch) -> dict[str, float]:
        """Minibatch regression of V_r and V_c on their GAE returns (+ L2 on weights), here.

        One permutation per pass from torch's global generator.
        """
        n = batch.obs.shape[0]
        perms = [torch.randperm(n) for _ in range(self.critic_iters)]
        losses = regress_critics(
            self.critic_r, self.critic_c, self.critic_optimizer,
            CriticTargets(batch.obs, batch.ret_r, batch.ret_c), perms,
            self._critic_minibatch(n), self.critic_l2, self.max_grad_norm,
            autograd=self.autograd_only,
        )
        assert losses is not None  # no stop condition here
        return {"loss_v": losses[0], "loss_vc": losses[1], "critic_helper": 0.0}

    def start_critic_update(self, batch: RolloutBatch, skip: int) -> _CriticJob | None:
        """Start the critic regression in the helper, if it is used for this update (else
        ``None``); the update's time is measured until :meth:`finish_critic_update`.

        The helper gets the permutations the global generator will draw after ``skip`` more
        draws of ``randperm(batch size)`` (the actor passes that come first); the generator
        itself is not advanced here.
        """
        self._update_start = time.perf_counter()
        if self.parallel_critics == "auto":
            self.critics_in_helper = self._critic_choice.choose()
        if not self.critics_in_helper:
            return None
        n = batch.obs.shape[0]
        generator = torch.Generator()
        generator.set_state(torch.get_rng_state())
        for _ in range(skip):
            torch.randperm(n, generator=generator)
        perms = [torch.randperm(n, generator=generator) for _ in range(self.critic_iters)]
        if self._critic_worker is None:
            self._critic_worker = CriticWorker(self.critic_r, self.critic_c,
                                               self.critic_optimizer)
        self._critic_worker.submit(
            self.critic_r, self.critic_c, self.critic_optimizer,
            CriticTargets(batch.obs, batch.ret_r, batch.ret_c), perms,
            self._critic_minibatch(n), self.critic_l2, self.max_grad_norm,
            autograd=self.autograd_only,
        )
        return _CriticJob(skip)

    def finish_critic_update(
        self, batch: RolloutBatch, job: _CriticJob | None, drawn: int
    ) -> dict[str, float]:
        """The critic update after ``drawn`` permutations were drawn since the job started.

        The helper's result is used when it got the right permutations (then the global
        generator draws them too, as a regression here would have); otherwise the job is
        cancelled and the critics regress here.
        """
        if job is not None and self._critic_worker is not None and job.skip == drawn:
            loss_v, loss_vc = self._critic_worker.result(
                self.critic_r, self.critic_c, self.critic_optimizer)
            n = batch.obs.shape[0]
            for _ in range(self.critic_iters):
                torch.randperm(n)
            stats = {"loss_v": loss_v, "loss_vc": loss_vc}
        else:
            if job is not None and self._critic_worker is not None:
                self._critic_worker.cancel()
            stats = self.update_critics(batch)
        self._critic_choice.record(job is not None, time.perf_counter() - self._update_start)
        stats["critic_helper"] = float(job is not None and job.skip == drawn)
        return stats

    # ----------------------------------------------------------------- helpers and state
    def env_snapshot(self) -> Any:
        """The training env for a checkpoint; with the rollout helper, its live sub-envs.

        ``None`` (with a warning, once) when the helper cannot pickle them: a resume then
        restarts the episodes in progress, as for an unpicklable env in this process.
        """
        if self._rollout_helper is None:
            return self.envs
        try:
            return self._rollout_helper.snapshot()
        except RuntimeError as exc:
            if not self._warned_unpicklable:
                logger.warning("the rollout helper cannot pickle the envs (%s): checkpoints "
                               "omit the env state; a resume will not be bit-identical", exc)
                self._warned_unpicklable = True
            return None

    def _stop_rollout_helper(self, fetch: bool) -> None:
        helper, self._rollout_helper = self._rollout_helper, None
        if helper is not None:
            if fetch:
                try:
                    helper.gather()  # the helper's sub-envs back into self.envs
                except RuntimeError:  # a rollout was in flight (an error interrupted it)
                    pass
            helper.close()

    def replace_envs(self, envs: gym.vector.VectorEnv) -> None:
        """Continue with ``envs``; a helper rolling out the old ones is stopped."""
        self._stop_rollout_helper(fetch=False)
        super().replace_envs(envs)

    def close_helpers(self) -> None:
        """Stop the helpers; the rollout helper's live envs become :attr:`envs` again."""
        self._stop_rollout_helper(fetch=True)
        if self._critic_worker is not None:
            self._critic_worker.close()
            self._critic_worker = None

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
        self._stop_rollout_helper(fetch=False)
        super().load_state_dict(state)
        self.actor.load_state_dict(state["actor"])
        self.critic_r.load_state_dict(state["critic_r"])
        self.critic_c.load_state_dict(state["critic_c"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        self.normalizer.load_state_dict(state["normalizer"])
        self.last_ep_cost, self.last_ep_length = state["last_ep"]

