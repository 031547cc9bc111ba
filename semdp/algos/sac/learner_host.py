"""Where SAC's learner runs: in the training process or in a process of its own (docs/semdp.md,
"The main job's loop").

Both hosts take the same calls from :class:`semdp.algos.sac.SAC`'s round loop --
``start(n_updates, size)`` when a round of collection begins, ``wait()`` when it ends,
``pull_actor(actor)`` to act with the new weights -- and give the same numbers:
:class:`InlineLearner` runs the updates inside ``wait()``, :class:`ProcessLearner` sends them to
a learner process (:mod:`semdp.algos.sac.learner_process`) that runs them while the training process
collects the round, on the other core. The learner process is a :class:`solvers.workers.Helper`:
it ignores SIGINT (a terminal's Ctrl-C reaches only the training process, which stops it), exits
when its connection closes, and fails with one :class:`~solvers.workers.HelperError` naming it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from semdp.algos.sac.learner import SACLearner
from semdp.algos.sac.replay import SharedReplayBuffer
from solvers.workers import Helper

#: Seconds to wait for a learner process to copy its state back when it is closed.
CLOSE_TIMEOUT_S = 10.0


class InlineLearner:
    """Runs the updates in the calling process (``wait()`` does the work)."""

    def __init__(self, core: SACLearner) -> None:
        self.core = core
        self._job: tuple[int, int] | None = None

    def start(self, n_updates: int, size: int) -> None:
        """Queue ``n_updates`` updates on the first ``size`` replay rows."""
        self._job = (n_updates, size) if n_updates > 0 else None

    def wait(self) -> dict[str, Any] | None:
        """Run the queued updates; their logs (None when there were none)."""
        job, self._job = self._job, None
        return self.core.run(*job) if job else None

    def pull_actor(self, actor: nn.Module) -> None:
        """Nothing to copy: the collector acts with the learner's own actor."""

    def state_dict(self) -> dict[str, Any]:
        """The learner's state."""
        return self.core.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore the learner's state."""
        self.core.load_state_dict(state)

    def close(self, keep_state: bool = True) -> None:
        """Nothing to stop."""


class ProcessLearner:
    """Runs the updates in a learner process on the shared replay buffer.

    The process is a spawned :class:`solvers.workers.Helper`
    (:class:`semdp.algos.sac.learner_process.LearnerServer`) that maps the replay file through the
    descriptor it inherits; it fails, dies and stops as every helper does (one
    :class:`~solvers.workers.HelperError` naming it).

    Args:
        core: the training process' learner: its settings build the process' learner, its state
            is sent with the first command; :meth:`close` copies the process' state back into it.
        buffer: the replay buffer, built with ``shared=True``.
        threads: torch threads of the learner process.
    """

    def __init__(self, core: SACLearner, buffer: SharedReplayBuffer, threads: int = 1) -> None:
        if buffer.fd is None:
            raise ValueError("ProcessLearner needs a SharedReplayBuffer built with shared=True")
        self.core = core
        self.helper = Helper.spawn("semdp.algos.sac.learner_process:LearnerServer",
                                   "semdp-learner", pass_fds=(buffer.fd,), threads=threads)
        self.helper.send(("init", core.settings, buffer.fd, buffer.layout, buffer.nbytes,
                          int(threads)))
        self._outstanding = 1
        self._loaded = False  # the core's state goes with the first command (the process is up)
        self._actor: np.ndarray | None = None

    # ----------------------------------------------------------------- protocol
    def _send(self, *request: Any) -> None:
        if not self._loaded:
            self._loaded = True
            self._send("load", self.core.state_dict())
        self.helper.send(request)
        self._outstanding += 1

    def _drain(self) -> Any:
        reply = None
        while self._outstanding:
            self._outstanding -= 1
            reply = self.helper.receive()
        return reply

    # ----------------------------------------------------------------- rounds
    def start(self, n_updates: int, size: int) -> None:
        """Send ``n_updates`` updates on the first ``size`` replay rows; returns at once."""
        if n_updates > 0:
            self._drain()
            self._send("run", n_updates, size)

    def wait(self) -> dict[str, Any] | None:
        """Block until the round's updates are done; their logs (None when there were none)."""
        reply = self._drain()
        if reply is None:
            return None
        logs, self._actor = reply
        return logs

    def pull_actor(self, actor: nn.Module) -> None:
        """Copy the process' actor weights after its last round into ``actor``."""
        if self._actor is not None:
            with torch.no_grad():
                nn.utils.vector_to_parameters(torch.from_numpy(self._actor), actor.parameters())

    def state_dict(self) -> dict[str, Any]:
        """The process' learner state (after the pending round)."""
        self.wait()
        self._send("state")
        return self._drain()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Replace the process' learner state."""
        self.wait()
        self._loaded = True
        self._send("load", state)
        self._drain()

    def close(self, keep_state: bool = True) -> None:
        """Stop the process; with ``keep_state`` first copy its state into :attr:`core`."""
        try:
            if keep_state and self._loaded and self.helper.alive:
                self.core.load_state_dict(self.state_dict())
        finally:
            self.helper.close(CLOSE_TIMEOUT_S)
