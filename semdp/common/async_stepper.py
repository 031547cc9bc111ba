"""Training envs stepped partly in a forked helper process, partly in the trainer, at once.

``vectorization="async"`` of the on-policy algorithms (semdp/README.md, "Throughput"): the
helper holds the sub-envs ``local..n-1`` as they were when it was forked and steps them while
the trainer steps ``0..local-1`` and evaluates its critics; both use
:class:`~semdp.common.vector_stepping.VectorStepper`, so every sub-env evolves exactly as it
would in the trainer alone (each has its own generator). Actions, observations, rewards, flags
and costs of the helper's sub-envs travel through shared memory; the pipe carries a one-byte
request per step and, when episodes end, their last observations and success entries.
"""

from __future__ import annotations

import copy
import mmap
import pickle
import time
import traceback
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.common.forked_worker import ForkedWorker
from semdp.common.vector_stepping import StepResult, VectorStepper

_STEP, _STATE = b"s", b"p"
_OK, _ERROR = b"d", b"e"
#: Pickle protocol of the helper's sub-envs (torch.save's default, as for in-process envs).
STATE_PROTOCOL = 2


class _SharedArrays:
    """Per-step arrays of ``n`` sub-envs in one anonymous shared mapping (inherited by fork)."""

    actions: np.ndarray
    obs: np.ndarray
    rewards: np.ndarray
    costs: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    busy_s: np.ndarray

    def __init__(self, envs: gym.vector.SyncVectorEnv, n: int) -> None:
        obs_space, act_space = envs.single_observation_space, envs.single_action_space
        layout = [
            ("actions", (n, *act_space.shape), act_space.dtype),
            ("obs", (n, *obs_space.shape), obs_space.dtype),
            ("rewards", (n,), np.dtype(np.float64)),
            ("costs", (n,), np.dtype(np.float64)),
            ("terminated", (n,), np.dtype(np.bool_)),
            ("truncated", (n,), np.dtype(np.bool_)),
            ("busy_s", (1,), np.dtype(np.float64)),
        ]
        sizes = [int(np.prod(shape)) * np.dtype(dtype).itemsize for _, shape, dtype in layout]
        offsets = np.cumsum([0, *[(s + 63) // 64 * 64 for s in sizes]])
        self._map = mmap.mmap(-1, max(int(offsets[-1]), 1))
        for (name, shape, dtype), offset in zip(layout, offsets[:-1], strict=True):
            view = np.frombuffer(self._map, dtype=dtype, count=int(np.prod(shape)),
                                 offset=int(offset))
            setattr(self, name, view.reshape(shape))


class _Server:
    """The helper's side: steps its sub-envs on request, results into the shared arrays."""

    def __init__(self, envs: gym.vector.SyncVectorEnv, indices: range,
                 shared: _SharedArrays) -> None:
        self.envs, self.indices, self.shared = envs, indices, shared
        self.stepper = VectorStepper(envs, indices)

    def __call__(self, request: bytes) -> bytes:
        try:
            if request == _STEP:
                return self._step()
            if request == _STATE:
                blobs = [pickle.dumps(self.envs.envs[i], protocol=STATE_PROTOCOL)
                         for i in self.indices]
                return _OK + pickle.dumps(blobs, protocol=pickle.HIGHEST_PROTOCOL)
            raise ValueError(f"unknown request {request!r}")
        except Exception:  # reported to the trainer, which raises it
            return _ERROR + traceback.format_exc().encode()

    def _step(self) -> bytes:
        start = time.perf_counter()
        s = self.shared
        result = self.stepper.step(s.actions.copy())
        s.obs[...] = result.obs
        s.rewards[...] = result.rewards
        s.costs[...] = result.costs
        s.terminated[...] = result.terminated
        s.truncated[...] = result.truncated
        extra = pickle.dumps((result.final_obs, result.final_infos)) if result.final_obs else b""
        s.busy_s[0] += time.perf_counter() - start
        return _OK + extra


class PickledEnv:
    """A sub-env pickled in the helper; pickling this pickles to that env (a checkpoint entry
    that unpickles to the sub-env itself, without a second pickling in the trainer)."""

    def __init__(self, blob: bytes) -> None:
        self.blob = blob

    def __reduce__(self) -> tuple[Callable[[bytes], Any], tuple[bytes]]:
        return pickle.loads, (self.blob,)


class AsyncStepper:
    """Steps ``envs`` with a forked helper; the interface of
    :class:`~semdp.common.vector_stepping.VectorStepper` (``step_async`` / ``step_wait``).

    Args:
        envs: the vector env as it is now; the helper continues its sub-envs from exactly this
            state (the trainer's copies of them are not stepped any more; :meth:`gather`
            brings them back).
        local: how many sub-envs (the first ones) the trainer steps itself in
            :meth:`step_wait`, while the helper steps the others.
    """

    def __init__(self, envs: gym.vector.SyncVectorEnv, local: int = 0) -> None:
        n = envs.num_envs
        if not 0 <= local < n:
            raise ValueError(f"local must be in [0, {n - 1}], got {local}")
        self.envs, self.local = envs, local
        self._here = VectorStepper(envs, range(local)) if local else None
        remote = range(local, n)
        VectorStepper(envs, remote)  # validates the autoreset mode before forking
        self._shared = _SharedArrays(envs, len(remote))
        self._worker = ForkedWorker(_Server(envs, remote, self._shared), name="semdp-envs")
        self._pending: np.ndarray | None = None

    def _reply(self) -> bytes:
        reply = self._worker.receive()
        if reply[:1] == _ERROR:
            raise RuntimeError(f"env helper process failed:\n{reply[1:].decode()}")
        return reply[1:]

    def step_async(self, actions: np.ndarray) -> None:
        """Start the helper's part of a step (rows per sub-env, the env's action dtype)."""
        if self._pending is not None:
            raise RuntimeError("step_async() while a step is running; call step_wait()")
        self._shared.actions[...] = actions[self.local:]
        self._worker.send(_STEP)
        self._pending = actions

    def step_wait(self) -> StepResult:
        """Step the trainer's part, then wait for the helper's; the whole step's result."""
        if self._pending is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._pending = self._pending, None
        here = self._here.step(actions[: self.local]) if self._here is not None else None
        extra = self._reply()
        s = self._shared
        final_obs, final_infos = pickle.loads(extra) if extra else ({}, {})
        there = StepResult(s.obs.copy(), s.rewards.copy(), s.terminated.copy(),
                           s.truncated.copy(), s.costs.copy(), final_obs, final_infos)
        return there if here is None else StepResult.concatenate(here, there)

    def step(self, actions: np.ndarray) -> StepResult:
        """One step, waiting for it."""
        self.step_async(actions)
        return self.step_wait()

    def _helper_blobs(self) -> list[bytes]:
        if self._pending is not None:
            raise RuntimeError("the envs were requested while a step is running")
        self._worker.send(_STATE)
        return pickle.loads(self._reply())

    def snapshot(self) -> gym.vector.SyncVectorEnv:
        """A copy of the vector env for a checkpoint: the trainer's sub-envs as they are, the
        helper's as pickles made there (as a checkpoint pickles sub-envs; they unpickle to the
        sub-envs). The helper keeps stepping its own; the trainer's env is not changed."""
        snapshot = copy.copy(self.envs)
        snapshot.envs = [*self.envs.envs[: self.local],
                         *(PickledEnv(blob) for blob in self._helper_blobs())]
        return snapshot

    def gather(self) -> gym.vector.SyncVectorEnv:
        """The trainer's vector env with the helper's sub-envs brought back (pickled there, as
        a checkpoint pickles sub-envs); the helper keeps stepping its own."""
        self.envs.envs[self.local:] = [pickle.loads(blob) for blob in self._helper_blobs()]
        return self.envs

    @property
    def busy_seconds(self) -> float:
        """Seconds the helper has spent stepping so far."""
        return float(self._shared.busy_s[0])

    def close(self) -> None:
        """Stop the helper (call :meth:`gather` first to keep its sub-envs)."""
        self._worker.close()
