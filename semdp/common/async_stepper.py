"""Training envs stepped in a forked helper process while the learner computes.

``vectorization="async"`` of the on-policy algorithms (semdp/README.md, "Throughput"): the
helper holds the sub-envs as they were when it was forked and steps them with
:class:`~semdp.common.vector_stepping.VectorStepper`, so they evolve exactly as they would in
the trainer. Actions, observations, rewards, flags and costs travel through shared memory; the
pipe carries a one-byte request per step and, when episodes end, their last observations and
success flags. :meth:`AsyncStepper.env_state` pickles the helper's vector env (for checkpoints:
the same round trip a checkpoint of in-process envs does).
"""

from __future__ import annotations

import mmap
import pickle
import time
import traceback
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.common.forked_worker import ForkedWorker
from semdp.common.vector_stepping import StepResult, VectorStepper

_STEP, _STATE = b"s", b"p"
_OK, _ERROR = b"d", b"e"
#: Pickle protocol of :meth:`AsyncStepper.env_state` (torch.save's default, as in-process).
STATE_PROTOCOL = 2


class _SharedArrays:
    """Per-step arrays in one anonymous shared mapping (inherited by the forked helper)."""

    def __init__(self, envs: gym.vector.SyncVectorEnv) -> None:
        n = envs.num_envs
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
            count = int(np.prod(shape))
            view = np.frombuffer(self._map, dtype=dtype, count=count, offset=int(offset))
            setattr(self, name, view.reshape(shape))

    actions: np.ndarray
    obs: np.ndarray
    rewards: np.ndarray
    costs: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    busy_s: np.ndarray


class _Server:
    """The helper's side: steps on request, writes the results into the shared arrays."""

    def __init__(self, envs: gym.vector.SyncVectorEnv, shared: _SharedArrays) -> None:
        self.envs, self.shared = envs, shared
        self.stepper = VectorStepper(envs)

    def __call__(self, request: bytes) -> bytes:
        try:
            if request == _STEP:
                return self._step()
            if request == _STATE:
                return _OK + pickle.dumps(self.envs, protocol=STATE_PROTOCOL)
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
        extra = pickle.dumps((result.final_obs, result.successes)) if result.final_obs else b""
        s.busy_s[0] += time.perf_counter() - start
        return _OK + extra


class PickledEnvs:
    """A pickled vector env that unpickles to the env itself (a checkpoint's ``envs`` entry)."""

    def __init__(self, data: bytes) -> None:
        self.data = data

    def __reduce__(self) -> tuple[Any, tuple[bytes]]:
        return pickle.loads, (self.data,)


class AsyncStepper:
    """Steps ``envs`` in a forked helper; the interface of
    :class:`~semdp.common.vector_stepping.VectorStepper` (``step_async`` / ``step_wait``).

    Args:
        envs: the vector env as it is now; the helper continues from exactly this state. The
            trainer's copy is not stepped any more (fetch the live one with :meth:`env_state`).
    """

    def __init__(self, envs: gym.vector.SyncVectorEnv) -> None:
        VectorStepper(envs)  # validates the autoreset mode before forking
        self._shared = _SharedArrays(envs)
        self._worker = ForkedWorker(_Server(envs, self._shared), name="semdp-envs")
        self._waiting = False

    def _reply(self) -> bytes:
        reply = self._worker.receive()
        if reply[:1] == _ERROR:
            raise RuntimeError(f"env helper process failed:\n{reply[1:].decode()}")
        return reply[1:]

    def step_async(self, actions: np.ndarray) -> None:
        """Start a step with ``actions`` (rows per sub-env, the env's action dtype)."""
        if self._waiting:
            raise RuntimeError("step_async() while a step is running; call step_wait()")
        self._shared.actions[...] = actions
        self._worker.send(_STEP)
        self._waiting = True

    def step_wait(self) -> StepResult:
        """Wait for the step started by :meth:`step_async`."""
        if not self._waiting:
            raise RuntimeError("step_wait() without step_async()")
        self._waiting = False
        extra = self._reply()
        s = self._shared
        final_obs, successes = pickle.loads(extra) if extra else ({}, {})
        return StepResult(s.obs.copy(), s.rewards.copy(), s.terminated.copy(),
                          s.truncated.copy(), s.costs.copy(), final_obs, successes)

    def step(self, actions: np.ndarray) -> StepResult:
        """One step, waiting for it."""
        self.step_async(actions)
        return self.step_wait()

    def env_state(self) -> bytes:
        """The helper's vector env, pickled (it takes the round trip a checkpoint takes)."""
        if self._waiting:
            raise RuntimeError("env_state() while a step is running")
        self._worker.send(_STATE)
        return self._reply()

    @property
    def busy_seconds(self) -> float:
        """Seconds the helper has spent stepping so far."""
        return float(self._shared.busy_s[0])

    def close(self) -> None:
        """Stop the helper (its envs are dropped; fetch them first with :meth:`env_state`)."""
        self._worker.close()
