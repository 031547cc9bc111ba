"""The helper-process rollout collector (``vectorization="async"``/``"auto"``): a forked helper
rolls out its share of the training sub-envs each epoch while the trainer rolls out the others.

:class:`HelperCollector` has the interface of the plain
:class:`~semdp.algos.rollout.LocalCollector`. The helper (:class:`RolloutHelper`) holds the
sub-envs ``rows`` as they were when it was forked, and each epoch, given this
epoch's actor, normaliser statistics and sampling noise, runs
:func:`~semdp.algos.rollout.roll_part` on them while the trainer runs it on the others; the
two never wait for each other within the epoch (see :mod:`semdp.algos.rollout` for why the
numbers are those of one process). Checkpoints take the helper's sub-envs as pickled in the
helper (the round trip a checkpoint does in the trainer).
"""

from __future__ import annotations

import copy
import logging
import pickle
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import torch

from semdp.algos.helpers.option_probe import FasterOption
from semdp.algos.rollout import RolloutPart, roll_part
from semdp.common.networks import GaussianActor
from semdp.common.normalization import RunningNormalizer
from semdp.common.vector_stepping import VectorStepper, stepper_for
from solvers.workers import Helper

logger = logging.getLogger(__name__)

#: Pickle protocol of the helper's sub-envs (torch.save's default, as for in-process envs).
STATE_PROTOCOL = 2
#: ``vectorization="auto"``: seconds per vector step of the envs (first rollout, in this
#: process) from which they move to the helper.
ASYNC_MIN_STEP_S = 2e-4
#: Fraction of the sub-envs the trainer rolls out itself (it also values the merged rollout,
#: so it takes a little less than half).
TRAINER_SHARE: tuple[int, int] = (2, 5)


def merge_parts(first: RolloutPart, second: RolloutPart) -> RolloutPart:
    """Both parts side by side, ``second``'s sub-envs after ``first``'s."""
    k = first.rewards.shape[1]

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(first, name), getattr(second, name)], axis=1)

    assert first.last_obs is not None and second.last_obs is not None
    return RolloutPart(
        cat("raw_obs"), cat("obs"), cat("actions"), cat("log_probs"), cat("rewards"),
        cat("costs"), cat("terminated"), cat("truncated"),
        {**first.final_obs, **{(t, k + i): o for (t, i), o in second.final_obs.items()}},
        np.concatenate([first.last_obs, second.last_obs]),
        first.simulation_s + second.simulation_s, first.policy_s + second.policy_s,
    )


class PickledEnv:
    """A sub-env pickled in the helper; pickling this pickles to that env (a checkpoint entry
    that unpickles to the sub-env itself, without a second pickling in the trainer)."""

    def __init__(self, blob: bytes) -> None:
        self.blob = blob

    def __reduce__(self) -> tuple[Callable[[bytes], Any], tuple[bytes]]:
        return pickle.loads, (self.blob,)


class _Server:
    """The helper's side, on its forked copies of the envs, actor and normaliser."""

    def __init__(
        self,
        envs: gym.vector.SyncVectorEnv,
        rows: range,
        actor: GaussianActor,
        normalizer: RunningNormalizer,
        to_env_action: Callable[[Any], np.ndarray],
    ) -> None:
        self.envs, self.rows = envs, rows
        self.actor, self.normalizer, self.to_env_action = actor, normalizer, to_env_action
        self.stepper = VectorStepper(envs, rows)

    def __call__(self, request: tuple[str, Any]) -> Any:
        kind, job = request
        if kind == "roll":
            self.actor.load_state_dict({k: torch.from_numpy(v) for k, v in job["actor"].items()})
            self.normalizer.load_state_dict(job["normalizer"])
            return roll_part(self.actor, self.normalizer, self.to_env_action, self.stepper,
                             self.rows, job["num_envs"], torch.from_numpy(job["noise"]),
                             job["obs"])
        if kind == "envs":
            return [pickle.dumps(self.envs.envs[i], protocol=STATE_PROTOCOL) for i in self.rows]
        raise ValueError(f"unknown request {kind!r}")


class RolloutHelper:
    """Rolls out the sub-envs ``rows`` of ``envs`` in a forked helper, one epoch per request.

    Args:
        envs: the training vector env as it is now (a plain ``SyncVectorEnv``); the helper
            continues the sub-envs ``rows`` from exactly this state (the trainer's copies of
            them are not stepped any more: :meth:`gather` brings them back).
        rows: the helper's sub-envs, the last ones (``range(local, num_envs)``).
        actor, normalizer, to_env_action: the trainer's policy (the helper loads this epoch's
            weights and statistics into its forked copies with every request).
    """

    def __init__(
        self,
        envs: gym.vector.SyncVectorEnv,
        rows: range,
        actor: GaussianActor,
        normalizer: RunningNormalizer,
        to_env_action: Callable[[Any], np.ndarray],
    ) -> None:
        if rows.stop != envs.num_envs or not 0 < rows.start < envs.num_envs:
            raise ValueError(f"rows must be range(local, {envs.num_envs}) with local > 0, "
                             f"got {rows}")
        self.envs, self.rows = envs, rows
        server = _Server(envs, rows, actor, normalizer, to_env_action)
        self._worker = Helper.fork(server, name="semdp-rollout")
        self._pending = False
        #: Seconds the helper spent stepping its envs so far.
        self.simulation_s = 0.0

    def start(
        self,
        actor: GaussianActor,
        normalizer: RunningNormalizer,
        noise: torch.Tensor,
        obs: np.ndarray,
    ) -> None:
        """Start this epoch's rollout of the helper's rows with ``noise`` from ``obs``."""
        if self._pending:
            raise RuntimeError("a rollout is already running in the helper")
        job = {
            "actor": {k: v.detach().numpy().copy() for k, v in actor.state_dict().items()},
            "normalizer": normalizer.state_dict(), "num_envs": self.envs.num_envs,
            "noise": noise.numpy(), "obs": np.asarray(obs),
        }  # fmt: skip
        self._worker.send(("roll", job))
        self._pending = True

    def result(self) -> RolloutPart:
        """Wait for the rollout started by :meth:`start`."""
        if not self._pending:
            raise RuntimeError("no rollout is running in the helper")
        self._pending = False
        part: RolloutPart = self._worker.receive()
        self.simulation_s += part.simulation_s
        return part

    def _blobs(self) -> list[bytes]:
        if self._pending:
            raise RuntimeError("the envs were requested while a rollout is running")
        return self._worker.request(("envs", None))

    def snapshot(self) -> gym.vector.SyncVectorEnv:
        """A copy of the vector env for a checkpoint: the trainer's sub-envs as they are, the
        helper's as pickles made there (they unpickle to the sub-envs). The helper keeps its
        own; the trainer's env is not changed."""
        snapshot = copy.copy(self.envs)
        snapshot.envs = [*self.envs.envs[: self.rows.start],
                         *(PickledEnv(blob) for blob in self._blobs())]
        return snapshot

    def gather(self) -> gym.vector.SyncVectorEnv:
        """The trainer's vector env with the helper's sub-envs brought back (pickled there, as
        a checkpoint pickles sub-envs); the helper keeps stepping its own."""
        self.envs.envs[self.rows.start:] = [pickle.loads(blob) for blob in self._blobs()]
        return self.envs

    def close(self) -> None:
        """Stop the helper (call :meth:`gather` first to keep its sub-envs)."""
        self._worker.close()


class HelperCollector:
    """Rolls out the last 3/5 of the sub-envs in a :class:`RolloutHelper`, the others here.

    Args:
        actor, normalizer, to_env_action: the algorithm's policy.
        mode: ``"async"`` (always the helper) or ``"auto"`` (``choice`` picks per epoch; envs
            whose vector step took less than :data:`ASYNC_MIN_STEP_S` stay here: the pipe costs
            more).
        choice: the measured choice between the two ways (``auto``).
    """

    def __init__(
        self,
        actor: GaussianActor,
        normalizer: RunningNormalizer,
        to_env_action: Callable[[Any], np.ndarray],
        mode: str,
        choice: FasterOption,
    ) -> None:
        self.actor, self.normalizer, self.to_env_action = actor, normalizer, to_env_action
        self.mode, self.choice = mode, choice
        #: Whether the envs are to step with the helper this epoch (``auto``: the choice).
        self.in_helper = mode == "async"
        #: Whether the latest rollout used the helper.
        self.used_helper = False
        self._helper: RolloutHelper | None = None
        self._warned = False

    def _helper_for(self, envs: gym.vector.SyncVectorEnv) -> RolloutHelper | None:
        if self.mode == "auto":
            self.in_helper = self.choice.choose()
        local = max(1, (envs.num_envs * TRAINER_SHARE[0]) // TRAINER_SHARE[1])
        if not self.in_helper or local >= envs.num_envs:
            self.stop(fetch=True)
            return None
        if self._helper is None:
            self._helper = RolloutHelper(envs, range(local, envs.num_envs), self.actor,
                                         self.normalizer, self.to_env_action)
        return self._helper

    def collect(
        self, envs: Any, obs: np.ndarray, noise: torch.Tensor, seconds: dict[str, float]
    ) -> RolloutPart:
        """The rollout of every sub-env (the helper's rows after this process's)."""
        perf = time.perf_counter
        start = perf()
        helper = self._helper_for(envs)
        n_steps, num_envs = noise.shape[0], envs.num_envs
        local = helper.rows.start if helper is not None else num_envs
        if helper is not None:
            helper.start(self.actor, self.normalizer, noise[:, local:], obs[local:])
            stepper: Any = VectorStepper(envs, range(local))
        else:
            stepper = stepper_for(envs)
        part = roll_part(self.actor, self.normalizer, self.to_env_action, stepper, range(local),
                         num_envs, noise[:, :local], obs[:local])
        seconds["policy"] += part.policy_s
        seconds["simulation"] += part.simulation_s
        # this process's vector step, scaled to all the sub-envs
        step_s = part.simulation_s * num_envs / max(local, 1) / n_steps
        if helper is not None:
            wait = perf()
            remote = helper.result()
            seconds["simulation"] += perf() - wait
            seconds["simulation_worker"] += remote.simulation_s
            part = merge_parts(part, remote)
        if step_s < ASYNC_MIN_STEP_S:  # cheaper than the pipe to a helper: the envs stay here
            self.choice.disallow()
        self.used_helper = helper is not None
        self.choice.record(self.in_helper, perf() - start)
        return part

    def snapshot(self, envs: Any) -> Any:
        """The training env for a checkpoint; with the helper, its live sub-envs.

        ``None`` (with a warning, once) when the helper cannot pickle them: a resume then
        restarts the episodes in progress, as for an unpicklable env in this process.
        """
        if self._helper is None:
            return envs
        try:
            return self._helper.snapshot()
        except RuntimeError as exc:
            if not self._warned:
                logger.warning("the rollout helper cannot pickle the envs (%s): checkpoints "
                               "omit the env state; a resume will not be bit-identical", exc)
                self._warned = True
            return None

    def stop(self, fetch: bool) -> None:
        """Stop the helper; with ``fetch`` its live sub-envs come back into the trainer's env."""
        helper, self._helper = self._helper, None
        if helper is not None:
            if fetch:
                try:
                    helper.gather()
                except RuntimeError:  # a rollout was in flight (an error interrupted it)
                    pass
            helper.close()
