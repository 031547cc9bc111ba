"""A helper process forked from the trainer, serving byte requests over a pipe.

The on-policy algorithms use a second core through such helpers (semdp/README.md,
"Throughput"): one steps the training envs, one regresses the critics. Forking (rather than
spawning) lets a helper start in milliseconds with the parent's objects as they are at that
moment -- the sub-envs continue bit for bit, without the pickled round trip that restoring a
pymunk world implies. Only where the platform offers ``fork`` (:func:`fork_available`).

A helper ignores SIGINT (the trainer handles Ctrl-C and shuts it down), closes the pipes of the
other helpers it inherited, and exits when its parent disappears, when asked to, or when the
pipe closes. :meth:`ForkedWorker.close` stops it (also at garbage collection and exit).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import weakref
from collections.abc import Callable
from multiprocessing.connection import Connection

logger = logging.getLogger(__name__)

#: Request that ends the helper's loop.
QUIT = b"\x00quit"
#: Seconds between checks that the parent is alive while the helper waits.
_PARENT_CHECK_S = 1.0
_open_parent_ends: weakref.WeakSet[Connection] = weakref.WeakSet()


def fork_available() -> bool:
    """Whether helpers can be forked on this platform."""
    return "fork" in mp.get_all_start_methods()


def _stop(process: mp.process.BaseProcess, conn: Connection) -> None:
    try:
        if not conn.closed:
            conn.send_bytes(QUIT)
    except (BrokenPipeError, OSError):
        pass
    process.join(timeout=5.0)
    if process.is_alive():  # pragma: no cover - a helper stuck in user code
        process.terminate()
        process.join(timeout=5.0)
    if not conn.closed:
        conn.close()


def _run_child(
    handler: Callable[[bytes], bytes | None], conn: Connection, others: list[Connection]
) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for other in others:  # pipes of the other helpers, inherited through the fork
        other.close()
    parent = os.getppid()
    while True:
        while not conn.poll(_PARENT_CHECK_S):
            if os.getppid() != parent:
                return
        try:
            request = conn.recv_bytes()
        except (EOFError, OSError):
            return
        if request == QUIT:
            return
        reply = handler(request)
        if reply is not None:
            conn.send_bytes(reply)


class ForkedWorker:
    """A forked helper running ``handler(request) -> reply`` for each request.

    Args:
        handler: called in the helper for every request (``bytes``); a ``bytes`` reply is sent
            back, ``None`` sends nothing. It may use any object of the parent, as forked.
        name: process name (shown by ``ps``).

    Raises:
        RuntimeError: where the platform cannot fork.
    """

    def __init__(self, handler: Callable[[bytes], bytes | None], name: str) -> None:
        if not fork_available():
            raise RuntimeError("helper processes need the 'fork' start method")
        ctx = mp.get_context("fork")
        parent_end, child_end = ctx.Pipe()
        others = [c for c in list(_open_parent_ends) if not c.closed]
        self._process = ctx.Process(
            target=_run_child, args=(handler, child_end, [parent_end, *others]), name=name,
            daemon=True,
        )
        self._process.start()
        child_end.close()
        self._conn = parent_end
        _open_parent_ends.add(parent_end)
        self._finalizer = weakref.finalize(self, _stop, self._process, parent_end)

    def send(self, request: bytes) -> None:
        """Send one request.

        Raises:
            RuntimeError: if the helper was closed or died.
        """
        try:
            self._conn.send_bytes(request)
        except (OSError, ValueError) as exc:
            raise RuntimeError(f"helper process {self._process.name} is not running") from exc

    def receive(self) -> bytes:
        """The next reply (blocks).

        Raises:
            RuntimeError: if the helper died.
        """
        try:
            return self._conn.recv_bytes()
        except (EOFError, OSError) as exc:
            raise RuntimeError(f"helper process {self._process.name} died "
                               f"(exit code {self._process.exitcode})") from exc

    def request(self, request: bytes) -> bytes:
        """Send one request and wait for its reply."""
        self.send(request)
        return self.receive()

    @property
    def alive(self) -> bool:
        """Whether the helper is running and its pipe open."""
        return self._finalizer.alive and self._process.is_alive()

    def close(self) -> None:
        """Stop the helper (idempotent)."""
        self._finalizer()
