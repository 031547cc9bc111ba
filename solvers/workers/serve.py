"""The helper's side of :mod:`solvers.workers`: answer each request with one reply.

Every request is a pickled object; every reply is the pickled pair ``(True, value)`` or
``(False, traceback)`` when the handler raised, so the caller re-raises it with the helper's
name (:class:`solvers.workers.helper.HelperError`). The loop ends on :data:`QUIT`, when the
connection closes (the caller ended or died) or, for a forked helper, when its parent process
changes (the caller was killed and the helper re-parented).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib
import os
import pickle
import signal
import sys
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

#: Raw request (not a pickle) that ends the loop.
QUIT = b"\x00quit"
#: Seconds between checks that the parent process is still the same.
PARENT_CHECK_S = 1.0

Handler = Callable[[Any], Any]


def dumps(value: Any) -> bytes:
    """The wire format: the standard pickler (torch's pickler would move tensors to shared
    memory, which needs a ``multiprocessing`` parent)."""
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


def _reply(conn: Connection, ok: bool, value: Any) -> None:
    try:
        blob = dumps((ok, value))
    except Exception:  # an unpicklable reply becomes an error the caller sees
        blob = dumps((False, traceback.format_exc()))
    conn.send_bytes(blob)


def set_process_name(name: str) -> None:
    """Show the helper as ``name`` in ``ps -o comm``, ``top`` and ``pgrep`` (Linux; the first 15
    bytes; elsewhere nothing happens)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        libc.prctl(15, ctypes.c_char_p(name.encode()[:15]), 0, 0, 0)  # PR_SET_NAME
    except (OSError, AttributeError):
        pass


def serve(handler: Handler, conn: Connection, parent: int | None = None) -> None:
    """Answer requests on ``conn`` with ``handler`` until :data:`QUIT` or end of connection.

    Args:
        handler: request -> reply; an exception is sent back as its traceback.
        conn: the helper's end of the connection.
        parent: pid whose disappearance ends the loop (forked helpers).
    """
    while True:
        if parent is not None:
            while not conn.poll(PARENT_CHECK_S):
                if os.getppid() != parent:
                    return
        try:
            raw = conn.recv_bytes()
        except (EOFError, OSError):
            return
        if raw == QUIT:
            return
        try:
            ok, value = True, handler(pickle.loads(raw))
        except BaseException:
            ok, value = False, traceback.format_exc()
        try:
            _reply(conn, ok, value)
        except OSError:  # the caller hung up
            return


def resolve(target: str) -> Callable[..., Handler]:
    """The callable ``"package.module:name"`` names."""
    module, _, name = target.partition(":")
    value: Any = importlib.import_module(module)
    for part in name.split("."):
        value = getattr(value, part)
    return value


def main(argv: list[str] | None = None) -> None:
    """Entry point of a spawned helper: ``<fd> <name> <target> [argument ...]``.

    The handler is ``target(*arguments)``; a failure to build it is sent back as the reply to
    the first request, then the helper exits.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C and stops us
    argv = sys.argv[1:] if argv is None else argv
    conn = Connection(int(argv[0]))
    set_process_name(argv[1])
    try:
        handler = resolve(argv[2])(*argv[3:])
    except BaseException:
        _reply(conn, False, traceback.format_exc())
        return
    serve(handler, conn)
