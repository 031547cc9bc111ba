"""Shared algorithm machinery: the epoch loop with logging, evaluation, checkpoints and resume
(SPEC §4.3), and on-policy rollout collection with reward and cost critics (SPEC §4.1).

Run directory written by :meth:`Algorithm.learn` (project contract): ``progress.csv`` (one row
per epoch), ``checkpoints/last.pt``, ``metrics.json``. A checkpoint holds everything needed to
continue bit-for-bit: network and optimiser states, normaliser statistics, multiplier and
schedule state, replay buffer, the pickled vector env (sub-env states included), the current
observation and partial-episode statistics, and the Python/NumPy/torch RNG states.
"""

from __future__ import annotations

import logging
import math
import pickle
import sys
import time
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import torch
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from semdp.common.buffers import RolloutBatch, RolloutBuffer
from semdp.common.logger import ProgressCSV, write_metrics
from semdp.common.networks import GaussianActor, ValueCritic
from semdp.common.normalization import RunningNormalizer
from semdp.common.seeding import get_rng_states, set_rng_states
from semdp.envs import split_step_infos

logger = logging.getLogger(__name__)

CHECKPOINT_NAME = "last.pt"
EVAL_SEED_OFFSET = 10_000


def _box(space: gym.Space, what: str) -> gym.spaces.Box:
    if not isinstance(space, gym.spaces.Box):
        raise ValueError(f"{what} must be a gymnasium Box space, got {space}")
    return space


def _nanmean(values: list[float]) -> float:
    return float(np.mean(values)) if values else math.nan


class Algorithm(ABC):
    """Base class: owns the vector envs, episode bookkeeping and the epoch loop.

    Args:
        envs: training vector env (SAME_STEP autoreset, see :mod:`semdp.envs`).
        eval_envs: separate vector env for evaluation with the deterministic (mean) action.
        seed: run seed; resets ``envs`` with it and derives evaluation seeds from it.
        steps_per_epoch: environment steps (summed over sub-envs) per epoch.
    """

    #: Algorithm-specific ``progress.csv`` columns (after the common ones).
    extra_columns: tuple[str, ...] = ()

    def __init__(
        self,
        envs: gym.vector.VectorEnv,
        eval_envs: gym.vector.VectorEnv | None,
        seed: int,
        steps_per_epoch: int,
    ) -> None:
        if steps_per_epoch < envs.num_envs:
            raise ValueError(
                f"steps_per_epoch ({steps_per_epoch}) must be >= env.num_envs ({envs.num_envs})"
            )
        self.envs, self.eval_envs = envs, eval_envs
        self.seed = int(seed)
        self.num_envs = envs.num_envs
        self.steps_per_vector_step = self.num_envs
        self.n_steps = math.ceil(steps_per_epoch / self.num_envs)
        self.steps_per_epoch = self.n_steps * self.num_envs
        obs_space = _box(envs.single_observation_space, "observation space")
        self.act_space = _box(envs.single_action_space, "action space")
        self.obs_dim = int(np.prod(obs_space.shape))
        self.act_dim = int(np.prod(self.act_space.shape))
        self._act_low = self.act_space.low.astype(np.float64)
        self._act_high = self.act_space.high.astype(np.float64)
        self.epoch = 0
        self.env_steps = 0
        self.wall_time = 0.0
        self.total_epochs = 1
        obs, _ = envs.reset(seed=self.seed)
        self._obs = self._flat_obs(obs)
        self._ep_ret = np.zeros(self.num_envs)
        self._ep_cost = np.zeros(self.num_envs)
        self._ep_len = np.zeros(self.num_envs, dtype=np.int64)
        self._episodes: list[tuple[float, float, int]] = []
        self._warned_unpicklable = False

    # ----------------------------------------------------------------- helpers
    def _flat_obs(self, obs: npt.ArrayLike) -> npt.NDArray[np.float64]:
        return np.asarray(obs, dtype=np.float64).reshape(-1, self.obs_dim)

    def to_env_action(self, unit_action: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """Map actions in [-1, 1] (clipped) to the env's Box bounds."""
        a = np.clip(np.asarray(unit_action, dtype=np.float64), -1.0, 1.0)
        scaled = self._act_low + 0.5 * (a + 1.0) * (self._act_high - self._act_low)
        return scaled.reshape(-1, *self.act_space.shape).astype(self.act_space.dtype)

    def _track(self, rewards: npt.ArrayLike, costs: npt.ArrayLike, ended: npt.ArrayLike) -> None:
        """Accumulate per-env episode statistics; finished episodes go to this epoch's list."""
        self._ep_ret += rewards
        self._ep_cost += costs
        self._ep_len += 1
        for i in np.flatnonzero(ended):
            self._episodes.append(
                (float(self._ep_ret[i]), float(self._ep_cost[i]), int(self._ep_len[i]))
            )
            self._ep_ret[i] = self._ep_cost[i] = 0.0
            self._ep_len[i] = 0

    def _pop_episode_stats(self) -> dict[str, float]:
        eps, self._episodes = self._episodes, []
        return {
            "ep_return": _nanmean([e[0] for e in eps]),
            "ep_cost": _nanmean([e[1] for e in eps]),
            "ep_length": _nanmean([e[2] for e in eps]),
            "episodes": len(eps),
        }

    # ----------------------------------------------------------------- interface
    @abstractmethod
    def train_epoch(self) -> dict[str, float]:
        """Collect ``steps_per_epoch`` env steps and update; return this epoch's log row.

        The row holds ``ep_return``, ``ep_cost``, ``ep_length`` (episodes finished this epoch),
        ``lagrange_multiplier``, ``cost_threshold`` and the :attr:`extra_columns`.
        """

    @abstractmethod
    def predict(self, obs: npt.ArrayLike, deterministic: bool = True) -> npt.NDArray[Any]:
        """Env-scaled actions for a batch of raw observations."""

    def evaluate(self, episodes: int, seed: int | None = None) -> dict[str, Any]:
        """Mean-action evaluation on ``eval_envs`` over exactly ``episodes`` episodes.

        Returns:
            ``{"episodes", "return_mean", "return_std", "cost_mean", "cost_std",
            "success_rate"}``; ``success_rate`` is ``None`` unless the env reports
            ``info["success"]`` (or ``"is_success"``) at episode end.
        """
        if episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {episodes}")
        if self.eval_envs is None:
            raise RuntimeError("no eval_envs were given to this algorithm")
        envs = self.eval_envs
        obs, _ = envs.reset(seed=self.seed + EVAL_SEED_OFFSET if seed is None else seed)
        n = envs.num_envs
        # A fixed quota of episodes per sub-env, so short episodes are not over-represented.
        quota = np.array([episodes // n + (i < episodes % n) for i in range(n)])
        ret, cost = np.zeros(n), np.zeros(n)
        results: list[tuple[float, float, float | None]] = []
        while len(results) < episodes:
            actions = self.predict(obs, deterministic=True)
            obs, rewards, term, trunc, infos = envs.step(actions)
            ended = np.logical_or(term, trunc)
            costs, _ = split_step_infos(obs, infos, ended)
            ret += rewards
            cost += costs
            for i in np.flatnonzero(ended):
                if quota[i] > 0:
                    quota[i] -= 1
                    info = infos["final_info"]
                    key = "success" if "success" in info else "is_success"
                    success = float(info[key][i]) if key in info else None
                    results.append((float(ret[i]), float(cost[i]), success))
                ret[i] = cost[i] = 0.0
        rets = np.array([r[0] for r in results])
        csts = np.array([r[1] for r in results])
        succ = [r[2] for r in results if r[2] is not None]
        return {
            "episodes": len(results),
            "return_mean": float(rets.mean()),
            "return_std": float(rets.std()),
            "cost_mean": float(csts.mean()),
            "cost_std": float(csts.std()),
            "success_rate": float(np.mean(succ)) if succ else None,
        }

    def state_dict(self) -> dict[str, Any]:
        """Loop counters, env state, partial episodes and RNG states (subclasses add theirs)."""
        return {
            "epoch": self.epoch,
            "env_steps": self.env_steps,
            "wall_time": self.wall_time,
            "envs": self.envs,
            "obs": self._obs.copy(),
            "episode_accumulators": (self._ep_ret.copy(), self._ep_cost.copy(),
                                     self._ep_len.copy()),
            "rng": get_rng_states(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (the training env is replaced by the pickled one)."""
        self.epoch, self.env_steps = state["epoch"], state["env_steps"]
        self.wall_time = state["wall_time"]
        if state["envs"] is not None:
            self.envs.close()
            self.envs = state["envs"]
            self._obs = state["obs"].copy()
            ret, cost, length = state["episode_accumulators"]
            self._ep_ret, self._ep_cost, self._ep_len = ret.copy(), cost.copy(), length.copy()
        else:  # the env was not picklable: restart its episodes deterministically
            obs, _ = self.envs.reset(seed=self.seed + 7919 * (self.epoch + 1))
            self._obs = self._flat_obs(obs)
        set_rng_states(state["rng"])

    # ----------------------------------------------------------------- the loop
    def save_checkpoint(self, path: Path) -> None:
        """``torch.save`` of :meth:`state_dict`.

        The vector env is pickled with it so that a resume is exact. An env that cannot be
        pickled (e.g. one holding a closure) is left out with a warning; resuming such a run
        restarts the episodes in progress from a reset seeded by ``(seed, epoch)``, so it
        continues correctly but not bit-for-bit.
        """
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        state = self.state_dict()
        try:
            torch.save({"algo": state}, tmp)
        except (AttributeError, TypeError, pickle.PicklingError) as exc:
            if not self._warned_unpicklable:
                logger.warning("env cannot be pickled (%s): checkpoints omit the env state; "
                               "a resume will not be bit-identical", exc)
                self._warned_unpicklable = True
            state["envs"] = None
            torch.save({"algo": state}, tmp)
        tmp.replace(path)

    def load_checkpoint(self, path: Path) -> None:
        """Load a checkpoint written by :meth:`save_checkpoint`."""
        self.load_state_dict(torch.load(path, weights_only=False)["algo"])

    def learn(
        self,
        total_steps: int,
        run_dir: str | Path,
        eval_every: int = 10,
        eval_episodes: int = 10,
        final_eval_episodes: int = 50,
        checkpoint_every: int = 1,
        resume: bool = False,
        metadata: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """Train for ``total_steps`` env steps, writing the run directory; return metrics.

        Args:
            total_steps: training budget (rounded up to whole epochs).
            run_dir: directory for ``progress.csv``, ``checkpoints/`` and ``metrics.json``.
            eval_every: periodic evaluation every this many epochs (0 = never).
            eval_episodes: episodes per periodic evaluation.
            final_eval_episodes: episodes of the final evaluation in ``metrics.json``.
            checkpoint_every: write ``checkpoints/last.pt`` every this many epochs (and last).
            resume: keep ``progress.csv`` rows up to the loaded epoch and append after them.
            metadata: extra keys for ``metrics.json`` (``algo``, ``env``, ``seed``).
        """
        if total_steps < 1:
            raise ValueError(f"total_steps must be >= 1, got {total_steps}")
        for name, value in (("eval_every", eval_every), ("checkpoint_every", checkpoint_every)):
            if value < 0:
                raise ValueError(f"{name} must be >= 0, got {value}")
        run_dir = Path(run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        ckpt = run_dir / "checkpoints" / CHECKPOINT_NAME
        self.total_epochs = math.ceil(total_steps / self.steps_per_epoch)
        csv = ProgressCSV(
            run_dir / "progress.csv", self.extra_columns, keep_epochs=self.epoch if resume else None
        )
        metrics: dict[str, Any] = {
            "status": "running", "error": None, **(metadata or {}), "seed": self.seed,
            "env_steps": self.env_steps, "wall_time_s": self.wall_time, "eval": None,
        }
        write_metrics(run_dir / "metrics.json", metrics)
        bar = tqdm(
            total=self.total_epochs, initial=self.epoch, unit="epoch",
            disable=not sys.stderr.isatty(), dynamic_ncols=True,
        )
        with bar, logging_redirect_tqdm():
            while self.epoch < self.total_epochs:
                start = time.perf_counter()
                stats = self.train_epoch()
                train_time = time.perf_counter() - start
                row: dict[str, Any] = {
                    "epoch": self.epoch, "env_steps": self.env_steps,
                    "fps": self.steps_per_epoch / max(train_time, 1e-9),
                    **{k: v for k, v in stats.items() if k != "episodes"},
                }
                if eval_every and self.epoch % eval_every == 0 and self.eval_envs is not None:
                    ev = self.evaluate(eval_episodes, seed=self.seed + EVAL_SEED_OFFSET
                                       + self.epoch)
                    row["eval_return"], row["eval_cost"] = ev["return_mean"], ev["cost_mean"]
                self.wall_time += time.perf_counter() - start
                row["wall_time_s"] = self.wall_time
                csv.write(row)
                last = self.epoch == self.total_epochs
                if (checkpoint_every and self.epoch % checkpoint_every == 0) or last:
                    self.save_checkpoint(ckpt)
                parts = [f"epoch {self.epoch}/{self.total_epochs}", f"steps {self.env_steps}"]
                for key, label in (("ep_return", "ret"), ("ep_cost", "cost"),
                                   ("lagrange_multiplier", "lambda"),
                                   ("cost_threshold", "d"), ("eval_return", "eval_ret"),
                                   ("eval_cost", "eval_cost")):
                    value = row.get(key)
                    if value is not None and not math.isnan(value):
                        parts.append(f"{label} {value:.3g}")
                parts.append(f"fps {row['fps']:.0f}")
                logger.info(" ".join(parts))
                bar.update(1)
                metrics.update(env_steps=self.env_steps, wall_time_s=self.wall_time)
                write_metrics(run_dir / "metrics.json", metrics)
        if final_eval_episodes > 0 and self.eval_envs is not None:
            metrics["eval"] = self.evaluate(final_eval_episodes)
        metrics["status"] = "completed"
        write_metrics(run_dir / "metrics.json", metrics)
        return metrics


class OnPolicyAlgorithm(Algorithm):
    """Rollouts with a Gaussian actor, reward critic and cost critic (shared by PPO and TRPO).

    Observation normalisation: the running statistics are updated once per epoch, after the
    rollout, so every sample of a batch was normalised the same way as the policy saw it.

    Args:
        envs, eval_envs, seed, steps_per_epoch: see :class:`Algorithm`.
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
    """

    base_columns: tuple[str, ...] = ("loss_v", "loss_vc", "entropy", "kl")

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
        self.critic_optimizer = torch.optim.Adam(
            [*self.critic_r.parameters(), *self.critic_c.parameters()], lr=critic_lr
        )
        self.normalizer = RunningNormalizer((self.obs_dim,), clip=obs_clip, enabled=obs_normalize)
        self.buffer = RolloutBuffer(self.n_steps, self.num_envs, self.obs_dim, self.act_dim)
        self.last_ep_cost: float | None = None
        self.last_ep_length: float | None = None

    # ----------------------------------------------------------------- acting
    def _tensor(self, obs: npt.ArrayLike) -> torch.Tensor:
        return torch.as_tensor(self.normalizer(self._flat_obs(obs)))

    def predict(self, obs: npt.ArrayLike, deterministic: bool = True) -> npt.NDArray[Any]:
        """Mean (or sampled) action, clipped and scaled to the env bounds."""
        with torch.no_grad():
            dist = self.actor.distribution(self._tensor(obs))
            a = dist.mean if deterministic else dist.sample()
        return self.to_env_action(a.numpy())

    def collect_rollout(self) -> dict[str, float]:
        """Fill the rollout buffer with ``n_steps`` vector steps; return episode statistics."""
        self.buffer.reset()
        raw_obs = np.zeros((self.n_steps, self.num_envs, self.obs_dim))
        boot_r = np.zeros((self.n_steps, self.num_envs))
        boot_c = np.zeros((self.n_steps, self.num_envs))
        for t in range(self.n_steps):
            raw_obs[t] = self._obs
            obs_t = self._tensor(self._obs)
            with torch.no_grad():
                dist = self.actor.distribution(obs_t)
                actions = dist.sample()
                log_probs = dist.log_prob(actions).sum(-1)
                v_r, v_c = self.critic_r(obs_t), self.critic_c(obs_t)
            next_obs, rewards, term, trunc, infos = self.envs.step(self.to_env_action(actions))
            ended = np.logical_or(term, trunc)
            costs, final_obs = split_step_infos(next_obs, infos, ended)
            timed_out = np.logical_and(ended, np.logical_not(term))
            if timed_out.any():  # bootstrap time-outs with V(true final observation)
                with torch.no_grad():
                    fo = self._tensor(final_obs[timed_out])
                    boot_r[t, timed_out] = self.critic_r(fo).numpy()
                    boot_c[t, timed_out] = self.critic_c(fo).numpy()
            self.buffer.add(
                obs=obs_t.numpy(), actions=actions.numpy(), log_probs=log_probs.numpy(),
                rewards=rewards, costs=costs, values_r=v_r.numpy(), values_c=v_c.numpy(),
                terminated=term, episode_end=ended,
            )
            self._track(rewards, costs, ended)
            self._obs = self._flat_obs(next_obs)
        with torch.no_grad():  # bootstrap the cut at the end of the rollout
            last = self._tensor(self._obs)
            last_r, last_c = self.critic_r(last).numpy(), self.critic_c(last).numpy()
        b = self.buffer
        b.next_values_r[:-1], b.next_values_r[-1] = b.values_r[1:], last_r
        b.next_values_c[:-1], b.next_values_c[-1] = b.values_c[1:], last_c
        ended = b.episode_end.astype(bool)
        b.next_values_r[ended] = boot_r[ended]
        b.next_values_c[ended] = boot_c[ended]
        self.normalizer.update(raw_obs.reshape(-1, self.obs_dim))
        self.env_steps += self.steps_per_epoch
        stats = self._pop_episode_stats()
        if stats["episodes"]:
            self.last_ep_cost, self.last_ep_length = stats["ep_cost"], stats["ep_length"]
        return stats

    def compute_batch(self) -> RolloutBatch:
        """GAE for reward and cost over the filled buffer."""
        return self.buffer.compute(self.gamma, self.gae_lambda, self.gamma_c, self.gae_lambda_c)

    def estimated_episode_cost(self) -> float:
        """J_c for the multiplier: mean cost of the episodes finished in the latest epochs.

        Falls back to the per-step cost of the current rollout times its length when no
        episode has finished yet.
        """
        if self.last_ep_cost is not None:
            return self.last_ep_cost
        return float(self.buffer.costs.mean() * self.n_steps)

    # ----------------------------------------------------------------- critics
    def update_critics(self, batch: RolloutBatch) -> dict[str, float]:
        """Minibatch regression of V_r and V_c on their GAE returns (+ L2 on weights)."""
        n = batch.obs.shape[0]
        mb = max(1, n // self.critic_minibatches)
        loss_v = loss_vc = torch.tensor(0.0)
        for _ in range(self.critic_iters):
            perm = torch.randperm(n)
            for start in range(0, n, mb):
                idx = perm[start : start + mb]
                obs = batch.obs[idx]
                loss_v = ((self.critic_r(obs) - batch.ret_r[idx]) ** 2).mean()
                loss_vc = ((self.critic_c(obs) - batch.ret_c[idx]) ** 2).mean()
                l2 = sum(
                    (p**2).sum()
                    for net in (self.critic_r, self.critic_c)
                    for name, p in net.named_parameters()
                    if name.endswith("weight")
                )
                self.critic_optimizer.zero_grad()
                (loss_v + loss_vc + self.critic_l2 * l2).backward()
                if self.max_grad_norm is not None:
                    torch.nn.utils.clip_grad_norm_(
                        [*self.critic_r.parameters(), *self.critic_c.parameters()],
                        self.max_grad_norm,
                    )
                self.critic_optimizer.step()
        return {"loss_v": loss_v.item(), "loss_vc": loss_vc.item()}

    # ----------------------------------------------------------------- state
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
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        self.actor.load_state_dict(state["actor"])
        self.critic_r.load_state_dict(state["critic_r"])
        self.critic_c.load_state_dict(state["critic_c"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        self.normalizer.load_state_dict(state["normalizer"])
        self.last_ep_cost, self.last_ep_length = state["last_ep"]
