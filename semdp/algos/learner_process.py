"""The SAC learner process: ``python -m semdp.algos.learner_process <socket fd>`` (started by
:class:`semdp.algos.learner_host.ProcessLearner`; semdp/README.md, "SAC learner process").

Answers commands on the inherited socket until "close" or until the socket closes: ``init``
(settings, the replay file's descriptor and layout, torch threads), ``load`` (a learner state),
``run`` (updates; replies with their logs and the new actor weights), ``state``. An exception
is sent back as its traceback; SIGINT is ignored (the training process stops this one).
"""

from __future__ import annotations

import signal
import sys
import traceback
from multiprocessing.connection import Connection
from typing import Any

from semdp.algos.learner_messages import receive_message, send_message


def serve(conn: Connection) -> None:
    """The command loop."""
    import torch

    from semdp.algos.replay_shared import attach
    from semdp.algos.sac_learner import SACLearner

    core: SACLearner | None = None
    while True:
        try:
            command, args = receive_message(conn)
        except (EOFError, OSError):
            return
        try:
            reply: Any = None
            if command == "init":
                settings, fd, layout, nbytes, threads = args
                torch.set_num_threads(int(threads))
                core = SACLearner(settings, attach(fd, layout, nbytes))
            elif core is None:
                raise RuntimeError(f"learner command {command!r} before init")
            elif command == "run":
                reply = (core.run(*args), core.actor_vector().numpy())
            elif command == "load":
                core.load_state_dict(args[0])
            elif command == "state":
                reply = core.state_dict()
            elif command != "close":
                raise ValueError(f"unknown learner command {command!r}")
            send_message(conn, ("ok", reply))
            if command == "close":
                return
        except (BrokenPipeError, EOFError, ConnectionError):
            return
        except BaseException:
            try:
                send_message(conn, ("error", traceback.format_exc()))
            except OSError:
                return


def main(argv: list[str] | None = None) -> None:
    """Entry point: serve on the socket whose descriptor is the first argument."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    argv = sys.argv[1:] if argv is None else argv
    serve(Connection(int(argv[0])))


if __name__ == "__main__":
    main()
