"""A forked helper that rolls out its share of the training sub-envs each epoch.

``vectorization="async"`` of the on-policy algorithms (semdp/README.md, "Throughput"): the
helper holds the sub-envs ``rows`` as they were when it was forked, and each epoch, given this
epoch's actor, normaliser statistics and sampling noise, runs
:func:`~semdp.algos.rollout.roll_part` on them while the trainer runs it on the others; the
two never wait for each other within the epoch (see :mod:`semdp.algos.rollout` for why the
numbers are those of one process). Checkpoints take the helper's sub-envs as pickled in the
helper (the round trip a checkpoint does in the trainer).
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import torch

from semdp.algos.rollout import RolloutPart, roll_part
from semdp.common.networks import GaussianActor
from semdp.common.normalization import RunningNormalizer
from semdp.common.vector_stepping import VectorStepper
from solvers.workers import Helper

#: Pickle protocol of the helper's sub-envs (torch.save's default, as for in-process envs).
STATE_PROTOCOL = 2


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
