"""Helper processes: start, request/reply messaging, timeouts, errors and shutdown.

One toolkit for every helper process of the project (the on-policy rollout and critic helpers,
the evaluation helpers, the SAC learner process, the planner's batch helpers). A
:class:`Helper` is started in one of two ways:

* :meth:`Helper.fork` -- a copy of the calling process that runs ``handler`` on its objects as
  they are at that moment (sub-envs continue bit for bit, nothing is pickled). The fork is made
  safe by construction: before the first request the helper sets every numeric runtime already
  loaded in the caller to one thread (:func:`single_threaded`), because a thread pool the caller
  started (GNU OpenMP under torch and MKL) does not exist in the copy and its first parallel
  region would wait forever for the missing threads.
* :meth:`Helper.spawn` -- a fresh interpreter (:func:`solvers.workers.serve.main`) running the
  handler ``target(*argv)``; nothing is inherited, so it suits callers that may have any state
  (the planner's batch helpers, the SAC learner process).

Both answer each request with one reply (:mod:`solvers.workers.serve`). One failure story: a
handler's exception, a helper that died (``kill -9``) or one that gave no reply in time raise
:class:`HelperError`, whose first line names the helper and what happened. One shutdown story:
helpers ignore SIGINT (the caller handles Ctrl-C and closes them), exit when their connection
closes or their parent changes, and :meth:`Helper.close` (also at garbage collection and exit)
asks them to quit, then terminates and finally kills them: no helper outlives its caller.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import signal
import socket
import subprocess
import sys
import time
import weakref
from collections.abc import Iterable, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from solvers.workers.serve import QUIT, Handler, dumps, serve, set_process_name

#: Seconds :meth:`Helper.close` waits for a helper to quit before terminating it.
CLOSE_TIMEOUT_S = 5.0
#: Seconds between liveness checks while waiting for a reply.
_LIVENESS_S = 1.0
#: The directory holding this project's packages (a spawned helper imports the same code).
_PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])
#: Environment of a spawned helper: one thread per numeric runtime unless the caller says.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
_open_caller_ends: weakref.WeakSet[Connection] = weakref.WeakSet()


class HelperError(RuntimeError):
    """A helper process failed, died or did not answer; the first line says which and how."""


def fork_available() -> bool:
    """Whether :meth:`Helper.fork` works on this platform."""
    return "fork" in mp.get_all_start_methods()


def single_threaded() -> None:
    """Set every numeric runtime the process has loaded to one intra-op thread.

    Called in a forked helper before anything else: torch (whose OpenMP and MKL pools do not
    survive ``fork``) is only touched if the caller had imported it.
    """
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


def describe_exit(code: int | None) -> str:
    """``exit code 3`` / ``killed by SIGKILL`` / ``still running``."""
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class _Forked:
    """A forked process behind the small interface :class:`Helper` uses."""

    def __init__(self, process: mp.process.BaseProcess) -> None:
        self.process = process
        self.pid = process.pid

    def poll(self) -> int | None:
        return None if self.process.is_alive() else self.process.exitcode

    def wait(self, timeout: float) -> int | None:
        self.process.join(timeout)
        return self.poll()

    def terminate(self) -> None:
        self.process.terminate()

    def kill(self) -> None:
        self.process.kill()


class _Spawned:
    """A ``subprocess.Popen`` behind the same interface."""

    def __init__(self, process: subprocess.Popen) -> None:
        self.process = process
        self.pid = process.pid

    def poll(self) -> int | None:
        return self.process.poll()

    def wait(self, timeout: float) -> int | None:
        try:
            return self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def terminate(self) -> None:
        self.process.terminate()

    def kill(self) -> None:
        self.process.kill()


def _forked_main(handler: Handler, conn: Connection, inherited: Sequence[Connection],
                 parent: int, name: str) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C and stops us
    set_process_name(name)
    for other in inherited:  # caller ends of every helper's connection, this one's included
        other.close()
    single_threaded()
    serve(handler, conn, parent=parent)


def _stop(process: _Forked | _Spawned, conn: Connection, timeout: float, owner: int) -> None:
    """Ask the helper to quit, then terminate, then kill it (idempotent). In a forked copy of
    the owner only the copy's end of the connection is closed: the helper is not its own."""
    if os.getpid() != owner:
        conn.close()
        return
    try:
        if not conn.closed:
            conn.send_bytes(QUIT)
    except (OSError, ValueError):
        pass
    if not conn.closed:
        conn.close()
    for escalate in (None, process.terminate, process.kill):
        if escalate is not None:
            escalate()
        if process.wait(timeout) is not None:
            return


class Helper:
    """One helper process answering requests; build it with :meth:`fork` or :meth:`spawn`."""

    def __init__(self, name: str, process: _Forked | _Spawned, conn: Connection) -> None:
        self.name = name
        self._process = process
        self._conn = conn
        self._owner = os.getpid()
        _open_caller_ends.add(conn)
        self._finalizer = weakref.finalize(self, _stop, process, conn, CLOSE_TIMEOUT_S,
                                           self._owner)

    # ----------------------------------------------------------------- starting
    @classmethod
    def fork(cls, handler: Handler, name: str) -> Helper:
        """A forked copy of this process answering ``handler(request)``.

        Raises:
            HelperError: where the platform cannot fork.
        """
        if not fork_available():
            raise HelperError(f"helper process {name}: the platform cannot fork")
        ctx = mp.get_context("fork")
        ours, theirs = ctx.Pipe()
        inherited = [ours, *(c for c in list(_open_caller_ends) if not c.closed)]
        process = ctx.Process(target=_forked_main, args=(handler, theirs, inherited,
                                                         os.getpid(), name), name=name,
                              daemon=True)
        process.start()
        theirs.close()
        return cls(name, _Forked(process), ours)

    @classmethod
    def spawn(cls, target: str, name: str, argv: Iterable[Any] = (),
              pass_fds: Sequence[int] = (), threads: int = 1, quiet: bool = False) -> Helper:
        """A fresh interpreter answering with the handler ``target(*argv)``.

        Args:
            target: ``"package.module:callable"``; called with ``argv`` as strings.
            name: the helper's name in errors.
            argv: the target's arguments.
            pass_fds: descriptors the helper inherits (e.g. a shared file it maps).
            threads: ``OMP_NUM_THREADS`` and friends in the helper (unless already set).
            quiet: discard the helper's standard output.
        """
        ours, theirs = socket.socketpair()
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [_PACKAGE_ROOT, *([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])])
        for variable in _THREAD_VARIABLES:
            env.setdefault(variable, str(int(threads)))
        try:
            process = subprocess.Popen(
                [sys.executable, "-c", "from solvers.workers.serve import main; main()",
                 str(theirs.fileno()), name, target, *(str(a) for a in argv)],
                pass_fds=(theirs.fileno(), *pass_fds), env=env, stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL if quiet else None,
                # a session of its own: a terminal's Ctrl-C reaches only the caller
                start_new_session=True,
            )
        finally:
            theirs.close()
        return cls(name, _Spawned(process), Connection(ours.detach()))

    # ----------------------------------------------------------------- messaging
    @property
    def pid(self) -> int | None:
        """The helper's process id."""
        return self._process.pid

    @property
    def connection(self) -> Connection:
        """The caller's end (for :func:`multiprocessing.connection.wait` over several)."""
        return self._conn

    @property
    def alive(self) -> bool:
        """Whether the helper runs and was not closed."""
        return self._finalizer.alive and self._process.poll() is None

    def _label(self) -> str:
        return f"helper process {self.name} (pid {self.pid})"

    def died(self) -> HelperError:
        """The error that says this helper has gone, and how."""
        code = self._process.wait(0.5) if self._finalizer.alive else self._process.poll()
        return HelperError(f"{self._label()} died ({describe_exit(code)})")

    def send(self, request: Any) -> None:
        """Send one request (its reply comes with :meth:`receive`).

        Raises:
            HelperError: when the helper has gone.
            pickle.PicklingError, TypeError: when the request does not pickle (nothing sent).
        """
        blob = dumps(request)
        try:
            self._conn.send_bytes(blob)
        except (OSError, ValueError) as exc:
            raise self.died() from exc

    def poll(self, timeout: float = 0.0) -> bool:
        """Whether a reply (or the end of the connection) can be read now."""
        try:
            return self._conn.poll(timeout)
        except (OSError, ValueError):
            return True

    def receive(self, timeout: float | None = None) -> Any:
        """The next reply (blocks up to ``timeout`` seconds; ``None``: as long as it lives).

        Raises:
            HelperError: the handler raised (with its traceback), the helper died, or no reply
                came within ``timeout``.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.poll(_LIVENESS_S if deadline is None
                            else max(0.0, min(_LIVENESS_S, deadline - time.monotonic()))):
            if self._process.poll() is not None:
                raise self.died()
            if deadline is not None and time.monotonic() >= deadline:
                raise HelperError(f"{self._label()} gave no reply within {timeout:g} s")
        try:
            ok, value = pickle.loads(self._conn.recv_bytes())
        except (EOFError, OSError, ValueError) as exc:
            raise self.died() from exc
        if not ok:
            raise HelperError(f"{self._label()} failed:\n{value}")
        return value

    def request(self, request: Any, timeout: float | None = None) -> Any:
        """:meth:`send` then :meth:`receive`."""
        self.send(request)
        return self.receive(timeout)

    def close(self, timeout: float = CLOSE_TIMEOUT_S) -> None:
        """Stop the helper: ask it to quit, after ``timeout`` s terminate it, then kill it
        (idempotent; in a forked copy of the caller only the copy's connection is closed)."""
        if self._finalizer.detach() is not None:
            _stop(self._process, self._conn, timeout, self._owner)


