"""The algorithm base: the epoch loop with logging, evaluation, checkpoints and resume.

Run directory written by :meth:`Algorithm.learn` (docs/training.md, "Run directory"):
``progress.csv`` (one row per epoch), ``checkpoints/last.pt``, ``metrics.json``. A checkpoint
holds everything needed to continue bit-for-bit: network and optimiser states, normaliser
statistics, multiplier and schedule state, replay buffer, the pickled vector env (sub-env states
included), the current observation and partial-episode statistics, and the Python/NumPy/torch
RNG states. On-policy rollouts are :mod:`semdp.algos.on_policy`'s.
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

from semdp.common.checkpoint_files import load_checkpoint_file, save_checkpoint_file
from semdp.common.logger import ProgressCSV, write_metrics
from semdp.common.phase_timer import PhaseTimer
from semdp.common.seeding import get_rng_states, set_rng_states
from semdp.common.vector_episodes import evaluate_episodes, summarize

logger = logging.getLogger(__name__)

CHECKPOINT_NAME = "last.pt"
#: The trained policy alone (what acting needs), written into the run directory at the end of
#: training: a few hundred kB that a reference folder keeps where it drops the checkpoint.
POLICY_NAME = "policy.pt"
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
        #: Seconds per phase of the work done so far (``semdp-bench train`` reports them).
        self.timer = PhaseTimer()
        #: Processes that share the evaluation sub-envs (:meth:`evaluate`; set by ``learn``).
        self.eval_workers = 1

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

    def evaluate(self, episodes: int, seed: int | None = None,
                 workers: int | None = None) -> dict[str, Any]:
        """Mean-action evaluation on ``eval_envs`` over exactly ``episodes`` episodes, a fixed
        quota per sub-env (:mod:`semdp.common.vector_episodes`).

        Args:
            episodes: how many.
            seed: vector reset seed (default: the run seed + ``EVAL_SEED_OFFSET``).
            workers: processes sharing the sub-envs (default :attr:`eval_workers`): the same
                layouts, reproducible numbers for a given value (floating-point batch effects
                make them differ across values).

        Returns:
            ``{"episodes", "return_mean", "return_std", "cost_mean", "cost_std",
            "success_rate"}``; ``success_rate`` is ``None`` unless the env reports
            ``info["success"]`` (or ``"is_success"``) at episode end.
        """
        if episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {episodes}")
        if self.eval_envs is None:
            raise RuntimeError("no eval_envs were given to this algorithm")
        results = evaluate_episodes(
            self.eval_envs, lambda obs: self.predict(obs, deterministic=True), episodes,
            self.seed + EVAL_SEED_OFFSET if seed is None else seed,
            self.eval_workers if workers is None else workers,
        )
        return summarize(results)

    def env_snapshot(self) -> Any:
        """The training vector env as a checkpoint stores it (pickled with the checkpoint)."""
        return self.envs

    def replace_envs(self, envs: gym.vector.VectorEnv) -> None:
        """Continue with ``envs`` (a restored training env) instead of the current one."""
        self.envs.close()
        self.envs = envs

    def close_helpers(self) -> None:  # noqa: B027  (a hook: no helpers at this level)
        """Stop helper processes; :meth:`learn` calls it when it returns (none here)."""

    def state_dict(self) -> dict[str, Any]:
        """Loop counters, env state, partial episodes and RNG states (subclasses add theirs)."""
        return {
            "epoch": self.epoch,
            "env_steps": self.env_steps,
            "wall_time": self.wall_time,
            "envs": self.env_snapshot(),
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
            self.replace_envs(state["envs"])
            self._obs = state["obs"].copy()
            ret, cost, length = state["episode_accumulators"]
            self._ep_ret, self._ep_cost, self._ep_len = ret.copy(), cost.copy(), length.copy()
        else:  # the env was not picklable: restart its episodes deterministically
            obs, _ = self.envs.reset(seed=self.seed + 7919 * (self.epoch + 1))
            self._obs = self._flat_obs(obs)
        set_rng_states(state["rng"])

    def policy_state(self) -> dict[str, Any]:
        """What :meth:`predict` needs: the actor's weights (subclasses add e.g. the observation
        normaliser)."""
        actor = self.actor  # type: ignore[attr-defined]
        return {"actor": {k: v.detach().clone() for k, v in actor.state_dict().items()}}

    def load_policy_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`policy_state` (the rest of the algorithm keeps its initial state)."""
        self.actor.load_state_dict(state["actor"])  # type: ignore[attr-defined]

    def save_policy(self, path: Path) -> None:
        """Write :meth:`policy_state` with the algorithm's class name (``policy.pt``)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        torch.save({"algorithm": type(self).__name__, "epoch": self.epoch,
                    "env_steps": self.env_steps, "policy": self.policy_state()}, tmp)
        tmp.replace(path)

    # ----------------------------------------------------------------- the loop
    def save_checkpoint(self, path: Path) -> None:
        """:meth:`state_dict` saved and signed (:mod:`semdp.common.checkpoint_files`).

        The vector env is pickled with it so that a resume is exact. An env that cannot be
        pickled (e.g. one holding a closure) is left out with a warning; resuming such a run
        restarts the episodes in progress from a reset seeded by ``(seed, epoch)``, so it
        continues correctly but not bit-for-bit.
        """
        state = self.state_dict()
        try:
            save_checkpoint_file({"algo": state}, path)
        except (AttributeError, TypeError, pickle.PicklingError) as exc:
            if not self._warned_unpicklable:
                logger.warning("env cannot be pickled (%s): checkpoints omit the env state; "
                               "a resume will not be bit-identical", exc)
                self._warned_unpicklable = True
            state["envs"] = None
            save_checkpoint_file({"algo": state}, path)

    def load_checkpoint(self, path: Path) -> None:
        """Load a checkpoint written by :meth:`save_checkpoint`: unpickled whole (it holds the
        envs), so only this account's own checkpoints are read (their signature is checked
        first; :mod:`semdp.common.checkpoint_files`); shared policies travel as ``policy.pt``
        (:mod:`semdp.common.policy_files`)."""
        self.load_state_dict(load_checkpoint_file(path)["algo"])

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
        eval_workers: int = 1,
    ) -> dict[str, Any]:
        """Train for ``total_steps`` env steps, writing the run directory; return metrics.

        Args:
            total_steps: training budget (rounded up to whole epochs).
            run_dir: directory for ``progress.csv``, ``checkpoints/``, ``metrics.json`` and, at
                the end, the trained policy (``policy.pt``).
            eval_every: periodic evaluation every this many epochs (0 = never).
            eval_episodes: episodes per periodic evaluation.
            final_eval_episodes: episodes of the final evaluation in ``metrics.json``.
            checkpoint_every: write ``checkpoints/last.pt`` every this many epochs (and last).
            resume: keep ``progress.csv`` rows up to the loaded epoch and append after them.
            metadata: extra keys for ``metrics.json`` (``algo``, ``env``, ``seed``).
            eval_workers: processes that share the evaluation sub-envs (forked helpers on the
                other cores; :meth:`evaluate`).
        """
        if total_steps < 1:
            raise ValueError(f"total_steps must be >= 1, got {total_steps}")
        for name, value in (("eval_every", eval_every), ("checkpoint_every", checkpoint_every)):
            if value < 0:
                raise ValueError(f"{name} must be >= 0, got {value}")
        if eval_workers < 1:
            raise ValueError(f"eval_workers must be >= 1, got {eval_workers}")
        self.eval_workers = int(eval_workers)
        run_dir = Path(run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
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
        try:
            with bar, logging_redirect_tqdm():
                while self.epoch < self.total_epochs:
                    self._epoch(run_dir, csv, metrics, eval_every, eval_episodes,
                                checkpoint_every)
                    bar.update(1)
        finally:  # helper processes end with the loop (also on errors and Ctrl-C)
            self.close_helpers()
        self.save_policy(run_dir / POLICY_NAME)
        if final_eval_episodes > 0 and self.eval_envs is not None:
            metrics["eval"] = self.evaluate(final_eval_episodes)
        metrics["status"] = "completed"
        write_metrics(run_dir / "metrics.json", metrics)
        return metrics

    def _epoch(
        self,
        run_dir: Path,
        csv: ProgressCSV,
        metrics: dict[str, Any],
        eval_every: int,
        eval_episodes: int,
        checkpoint_every: int,
    ) -> None:
        """One epoch of :meth:`learn`: train, evaluate, write the row, checkpoint, log."""
        start = time.perf_counter()
        stats = self.train_epoch()
        train_time = time.perf_counter() - start
        row: dict[str, Any] = {
            "epoch": self.epoch, "env_steps": self.env_steps,
            "fps": self.steps_per_epoch / max(train_time, 1e-9),
            **{k: v for k, v in stats.items() if k != "episodes"},
        }
        if eval_every and self.epoch % eval_every == 0 and self.eval_envs is not None:
            ev = self.evaluate(eval_episodes, seed=self.seed + EVAL_SEED_OFFSET + self.epoch)
            row["eval_return"], row["eval_cost"] = ev["return_mean"], ev["cost_mean"]
        self.wall_time += time.perf_counter() - start
        row["wall_time_s"] = self.wall_time
        csv.write(row)
        last = self.epoch == self.total_epochs
        if (checkpoint_every and self.epoch % checkpoint_every == 0) or last:
            self.save_checkpoint(run_dir / "checkpoints" / CHECKPOINT_NAME)
        parts = [f"epoch {self.epoch}/{self.total_epochs}", f"steps {self.env_steps}"]
        for key, label in (("ep_return", "ret"), ("ep_cost", "cost"),
                           ("lagrange_multiplier", "lambda"), ("cost_threshold", "d"),
                           ("eval_return", "eval_ret"), ("eval_cost", "eval_cost")):
            value = row.get(key)
            if value is not None and not math.isnan(value):
                parts.append(f"{label} {value:.3g}")
        parts.append(f"fps {row['fps']:.0f}")
        logger.info(" ".join(parts))
        metrics.update(env_steps=self.env_steps, wall_time_s=self.wall_time)
        write_metrics(run_dir / "metrics.json", metrics)
