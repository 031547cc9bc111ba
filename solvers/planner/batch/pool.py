"""The helper processes of :func:`solvers.planner.batch.planning.plan_batch` (caller side).

CasADi (IPOPT and the LM kernels) keeps the GIL while it evaluates, so Python threads cannot run
two solves at once: a thread pool of planner clones measured 0.9-1.0x the loop for IPOPT and LM.
The batch entry point therefore shares the problems with helper processes. Each helper is a
fresh interpreter (:meth:`solvers.workers.Helper.spawn`, not a fork: the caller's state and
``__main__`` are not copied) running :class:`solvers.planner.batch.server.BatchServer`. The pool
knows no planner class: it sends a pickled *factory* (a callable returning a
:class:`~solvers.planner.batch.claims.BatchSolver`), which each helper calls once per planner
configuration. The problems are shared through the page of claims of
:mod:`solvers.planner.batch.claims`; the caller waits for the helpers that claimed problems and
solves whatever is still missing itself (a helper that died), so a batch always completes. By
default the pool also measures whether sharing pays (:meth:`HelperPool.choose_shared`).

One pool serves every planner of a process; it is created on first use, belongs to the process
that created it (a forked child starts its own) and is shut down at exit.
"""

from __future__ import annotations

import atexit
import hashlib
import logging
import mmap
import os
import pickle
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import wait
from typing import Any

from solvers.planner.batch.claims import (
    CAPACITY,
    MAIN_ID,
    SIZE,
    BatchSolver,
    Task,
    attempt,
    claim,
    close_batch,
    open_batch,
    owner,
)
from solvers.workers import Helper, HelperError

logger = logging.getLogger(__name__)

#: With the default worker count, every this many batches of one planner and size run the way
#: (shared or here alone) currently measured slower, so the choice follows the machine's load.
EXPLORE_EVERY = 8
#: Decay per batch of each way's sums of wall time and work (about the last ten batches count).
TIMING_DECAY = 0.9
#: Helpers that may die (and be replaced) before the pool stops starting new ones.
MAX_LOST = 3


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover (macOS, Windows)
        return os.cpu_count() or 1


def default_workers() -> int:
    """Processes ``plan_batch`` uses by default: ``min(2, usable CPUs)``."""
    return max(1, min(2, usable_cpus()))


def factory_blob(factory: Callable[[], BatchSolver]) -> tuple[bytes, bytes]:
    """The pickled factory of a planner configuration and its digest (the helpers build and
    keep one planner per digest)."""
    blob = pickle.dumps(factory, protocol=pickle.HIGHEST_PROTOCOL)
    return blob, hashlib.sha1(blob).digest()


class _Helper:
    """One helper process (:class:`solvers.workers.Helper`) and what the pool knows of it."""

    def __init__(self, ident: int, shared_fd: int) -> None:
        self.ident = ident
        self.process = Helper.spawn(
            "solvers.planner.batch.server:BatchServer", f"planner-batch-{ident}",
            argv=(shared_fd, ident), pass_fds=(shared_fd,), quiet=True)
        self.ready: set[bytes] = set()  # planner digests registered and warmed up
        self.asked: set[bytes] = set()  # digests sent for registration
        self.outstanding = 0  # batches sent and not answered yet
        self.alive = True

    def send(self, message: object) -> bool:
        """Send ``message``; False when the helper has gone or the message does not pickle."""
        try:
            self.process.send(message)
            return True
        except HelperError:
            self.close()
        except Exception as error:  # pickling fails before anything is written
            logger.warning("could not send a batch to planner helper %d: %r", self.ident, error)
        return False

    def poll(self) -> bool:
        """Whether a message (or the helper's end) can be read now."""
        return self.alive and self.process.poll(0)

    def receive(self) -> tuple[Any, ...] | None:
        """The next message, or None when the helper has gone."""
        try:
            return self.process.receive()
        except HelperError as error:
            logger.warning("%s", str(error).splitlines()[0])
            self.close()
            return None

    def close(self, *, wait_s: float = 0.0) -> None:
        self.alive = False
        self.process.close(timeout=max(wait_s, 0.1))

    def abandon(self) -> None:
        """Drop a helper inherited through a fork (its owner keeps it)."""
        self.alive = False
        self.process.close()


class HelperPool:
    """The helper processes of this process (see the module docstring)."""

    def __init__(self) -> None:
        self.pid = os.getpid()
        self._file = tempfile.TemporaryFile()
        self._file.truncate(SIZE)
        self.shared = mmap.mmap(self._file.fileno(), SIZE)
        self.helpers: list[_Helper] = []
        self.batch_id = 0
        self.lock = threading.Lock()
        #: Problems solved by helpers (for tests and benchmarks).
        self.solved_by_helpers = 0
        self.lost = 0  # helpers that died or could not start
        self.warned = False
        #: (planner digest, batch size) -> [shared, here alone, batches]; each way as decayed
        #: sums [wall time (s), work] or None before its first batch.
        self.timings: dict[tuple[bytes, int], list[Any]] = {}

    # ---------------------------------------------------------------- default: measured choice
    def choose_shared(self, key: tuple[bytes, int]) -> bool:
        """Whether the next batch of this planner configuration and size should be shared.

        Both ways are tried first; then the one with the lower wall time per unit of work (see
        :meth:`record`) is used, except every :data:`EXPLORE_EVERY`-th batch, which runs the
        other way to follow changes in the machine's load.
        """
        timing = self.timings.setdefault(key, [None, None, 0])
        timing[2] += 1
        if timing[0] is None:
            return True
        if timing[1] is None:
            return False
        faster_shared = timing[0][0] * timing[1][1] <= timing[1][0] * timing[0][1]
        return (not faster_shared) if timing[2] % EXPLORE_EVERY == 0 else faster_shared

    def record(self, key: tuple[bytes, int], shared: bool, seconds: float, work: float) -> None:
        """Add a batch's wall time and work to its way's decayed sums.

        ``work`` normalises for how hard the batch's problems were (the planner passes the sum
        of solver iterations plus two per problem, the same whichever way a problem is solved);
        the ratio of the sums weighs each batch by its work, which keeps one slow problem from
        swinging the choice.
        """
        timing = self.timings.setdefault(key, [None, None, 0])
        slot = 0 if shared else 1
        old = timing[slot] or [0.0, 0.0]
        timing[slot] = [TIMING_DECAY * old[0] + seconds, TIMING_DECAY * old[1] + max(work, 1e-9)]

    # ---------------------------------------------------------------- helpers
    def _ensure(self, count: int) -> list[_Helper]:
        for helper in self.helpers:
            if not helper.alive:
                self.lost += 1
                helper.close(wait_s=1.0)  # reap it (kill it if it still runs)
        self.helpers = [h for h in self.helpers if h.alive]
        used = {h.ident for h in self.helpers}
        while len(self.helpers) < count and self.lost <= MAX_LOST:
            ident = min(set(range(MAIN_ID + 1, 256)) - used)
            used.add(ident)
            try:
                self.helpers.append(_Helper(ident, self._file.fileno()))
            except (OSError, ValueError) as error:  # no interpreter, no pass_fds (Windows)
                logger.warning("could not start a planner helper process: %r", error)
                self.lost = MAX_LOST + 1  # do not try again
                break
        if self.lost > MAX_LOST and not self.warned:
            self.warned = True
            logger.warning("planner batch helpers disabled after %d lost; plan_batch now "
                           "solves one problem after the other", self.lost)
        return self.helpers[:count]

    def _handle(self, helper: _Helper, message: tuple[Any, ...]) -> None:
        if message[0] == "registered":
            _, digest, error = message
            if error is None:
                helper.ready.add(digest)
            else:
                logger.warning("planner helper %d could not build the planner: %s",
                               helper.ident, error)
        elif message[0] == "done":
            helper.outstanding -= 1

    def _drain(self, helpers: Sequence[_Helper]) -> None:
        for helper in helpers:
            while helper.poll():
                message = helper.receive()
                if message is not None:
                    self._handle(helper, message)

    def prepare(self, count: int, digest: bytes, blob: bytes) -> list[_Helper]:
        """Start up to ``count`` helpers and register the planner; return the ready ones."""
        helpers = self._ensure(count)
        self._drain(helpers)
        for helper in helpers:
            if helper.alive and digest not in helper.asked:
                helper.asked.add(digest)
                helper.send(("register", digest, blob))
        return [h for h in helpers if h.alive and digest in h.ready and h.outstanding == 0]

    def wait_ready(self, count: int, digest: bytes, blob: bytes, timeout: float) -> int:
        """Like :meth:`prepare`, but wait up to ``timeout`` s until every helper is ready."""
        deadline = time.monotonic() + timeout
        while True:
            ready = self.prepare(count, digest, blob)
            alive = [h for h in self.helpers[:count] if h.alive]
            if len(ready) == len(alive) or time.monotonic() >= deadline:
                return len(ready)
            wait([h.process.connection for h in alive],
                 timeout=max(0.0, deadline - time.monotonic()))

    def shutdown(self) -> None:
        for helper in self.helpers:
            helper.close(wait_s=2.0)
        self.helpers = []

    # ---------------------------------------------------------------- batches
    def run(
        self,
        solve: Callable[[Task], Any],
        tasks: Sequence[Task],
        wire: Sequence[Task],
        helpers: Sequence[_Helper],
        digest: bytes,
    ) -> list[Any]:
        """Solve ``tasks`` here and in ``helpers``; per task a result or the exception raised.

        ``wire`` holds the same tasks as sent to the helpers (equal values, cheaper to pickle).
        """
        results: list[Any] = [None] * len(tasks)
        for lo in range(0, len(tasks), CAPACITY):
            chunk = list(tasks[lo : lo + CAPACITY])
            results[lo : lo + len(chunk)] = self._round(
                solve, chunk, list(wire[lo : lo + CAPACITY]), helpers, digest
            )
        return results

    def _round(
        self, solve: Callable[[Task], Any], tasks: list[Task], wire: list[Task],
        helpers: Sequence[_Helper], digest: bytes,
    ) -> list[Any]:
        n = len(tasks)
        shared = self.shared
        self.batch_id += 1
        bid = self.batch_id
        open_batch(shared, bid, n)
        parties = [h for h in helpers if h.alive]
        sent = []
        for k, helper in enumerate(parties, start=1):
            if helper.send(("batch", bid, digest, wire, (k * n) // (len(parties) + 1))):
                helper.outstanding += 1
                sent.append(helper)
        results: list[Any] = [None] * n
        done = [False] * n
        try:
            for k in range(n):
                if claim(shared, k, MAIN_ID):
                    results[k], done[k] = attempt(solve, tasks[k]), True
            owners = {owner(shared, k) for k in range(n) if not done[k]}
            for helper in sent:
                if helper.ident not in owners:
                    continue  # it answers later; the answer is dropped
                reply = self._await(helper, bid)
                for k, value in reply:
                    if not done[k]:
                        results[k], done[k] = value, True
                        self.solved_by_helpers += 1
        finally:
            close_batch(shared)
        for k in range(n):  # claimed by a helper that has gone
            if not done[k]:
                results[k], done[k] = attempt(solve, tasks[k]), True
        return results

    def _await(self, helper: _Helper, bid: int) -> list[tuple[int, Any]]:
        while helper.alive:
            message = helper.receive()
            if message is None:
                break
            self._handle(helper, message)
            if message[0] == "done" and message[1] == bid:
                return list(message[2])
        return []


_POOL: HelperPool | None = None
_POOL_LOCK = threading.Lock()


def get_pool() -> HelperPool:
    """This process' helper pool (created on first use)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is not None and _POOL.pid != os.getpid():
            for helper in _POOL.helpers:  # inherited through fork: not ours
                helper.abandon()
            _POOL = None
        if _POOL is None:
            _POOL = HelperPool()
        return _POOL


def shutdown_pool() -> None:
    """Stop this process' helper processes (a later batch starts new ones)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is not None and _POOL.pid == os.getpid():
            _POOL.shutdown()
        _POOL = None


atexit.register(shutdown_pool)
