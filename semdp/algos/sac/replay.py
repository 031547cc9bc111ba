"""SAC's replay buffer, in torch tensors that a learner process can share (docs/semdp.md,
"The main job's loop"); every SAC loop uses it.

The rows live in torch tensors, written through NumPy views by the collecting process and read with
``index_select`` by :class:`~semdp.algos.sac.learner.SACLearner`. With ``shared`` the tensors
are views of one memory-mapped file that is unlinked at once (in ``/dev/shm`` where it exists):
its descriptor, handed to the learner process (:func:`attach`), is the only name it has, so
nothing is left behind however the processes end. Rows are only written between learner
rounds, so a learner never reads a half-written row.
"""

from __future__ import annotations

import mmap
import os
import tempfile
from typing import Any

import numpy as np
import torch

#: Names of the stored fields, in ``state_dict`` order.
FIELDS: tuple[str, ...] = ("obs", "next_obs", "actions", "rewards", "costs", "terminated",
                           "horizons")


class SharedReplayBuffer:
    """Circular buffer of raw transitions.

    Args:
        capacity: transitions kept.
        obs_dim, act_dim: sizes of an observation and an action.
        shared: place the tensors in shared memory (for a learner process).
    """

    def __init__(self, capacity: int, obs_dim: int, act_dim: int, shared: bool = False) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = int(capacity)
        shapes = {"obs": (capacity, obs_dim), "next_obs": (capacity, obs_dim),
                  "actions": (capacity, act_dim), "rewards": (capacity,),
                  "costs": (capacity,), "terminated": (capacity,), "horizons": (capacity,)}
        self.layout: list[tuple[str, tuple[int, ...], int]] = []
        offset = 0
        for name, shape in shapes.items():
            self.layout.append((name, shape, offset))
            offset += 4 * int(np.prod(shape))
        self.nbytes = offset
        self.fd: int | None = None
        if shared:
            directory = "/dev/shm" if os.path.isdir("/dev/shm") else tempfile.gettempdir()
            self.fd, path = tempfile.mkstemp(prefix="semdp-replay-", dir=directory)
            os.unlink(path)
            os.ftruncate(self.fd, self.nbytes)
            self.tensors = attach(self.fd, self.layout, self.nbytes)
        else:
            self.tensors = {name: torch.zeros(shape, dtype=torch.float32)
                            for name, shape, _ in self.layout}
        self.arrays: dict[str, np.ndarray] = {k: t.numpy() for k, t in self.tensors.items()}
        self.pos, self.size = 0, 0

    def add_batch(
        self,
        obs: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        costs: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        horizons: np.ndarray | None = None,
    ) -> None:
        """Store ``n`` transitions (leading axis), oldest first, overwriting the oldest rows.

        ``horizons``: env steps summed in each row's reward (n-step rows,
        :mod:`semdp.algos.sac.n_step`); None for one-step transitions (1).
        """
        if horizons is None:
            horizons = np.ones(len(rewards), dtype=np.float32)
        rows = {"obs": obs, "actions": actions, "rewards": rewards, "costs": costs,
                "next_obs": next_obs, "terminated": terminated, "horizons": horizons}
        rows = {name: np.asarray(values, dtype=np.float32) for name, values in rows.items()}
        n, start = len(rows["rewards"]), 0
        while start < n:
            take = min(n - start, self.capacity - self.pos)
            for name, values in rows.items():
                self.arrays[name][self.pos:self.pos + take] = values[start:start + take]
            self.pos = (self.pos + take) % self.capacity
            self.size = min(self.size + take, self.capacity)
            start += take

    def state_dict(self) -> dict[str, Any]:
        """Filled part of the storage and the write position."""
        n = self.size
        return {"pos": self.pos, "size": n,
                **{name: self.arrays[name][:n].copy() for name in FIELDS}}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (one-step horizons where a checkpoint predates them)."""
        n = state["size"]
        for name in FIELDS:
            self.arrays[name][:n] = state[name] if name in state else 1.0
        self.pos, self.size = state["pos"], n


def attach(
    fd: int, layout: list[tuple[str, tuple[int, ...], int]], nbytes: int
) -> dict[str, torch.Tensor]:
    """Tensors over the shared file ``fd`` (layout of :attr:`SharedReplayBuffer.layout`)."""
    memory = mmap.mmap(fd, nbytes)
    return {name: torch.frombuffer(memory, dtype=torch.float32, count=int(np.prod(shape)),
                                   offset=offset).view(shape)
            for name, shape, offset in layout}
