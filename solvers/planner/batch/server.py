"""A helper process of :func:`solvers.planner.batch.planning.plan_batch` (helper side).

:class:`BatchServer` is the request handler a helper runs (:class:`solvers.workers.Helper`): it
builds and warms up the planners it is sent as pickled factories and solves its share of each
batch through the page of claims (:mod:`solvers.planner.batch.claims`).
"""

from __future__ import annotations

import mmap
import pickle
from functools import partial
from typing import Any

from solvers.planner.batch.claims import (
    SIZE,
    BatchSolver,
    Failure,
    claim_and_solve,
    solve_task,
)


class BatchServer:
    """A helper's handler (``argv``: the shared page's descriptor and the helper's id).

    Requests: ``("register", digest, factory blob)`` builds and warms up a planner
    (reply ``("registered", digest, error or None)``); ``("batch", id, digest, tasks, offset)``
    claims and solves problems from ``offset`` on (reply ``("done", id, [(k, result), ...])``;
    an exception that does not pickle is sent as a ``RuntimeError`` with its repr).
    """

    def __init__(self, shared_fd: str, ident: str) -> None:
        self.shared = mmap.mmap(int(shared_fd), SIZE)
        self.ident = int(ident)
        self.planners: dict[bytes, BatchSolver] = {}

    def __call__(self, message: tuple[Any, ...]) -> tuple[Any, ...]:
        if message[0] == "register":
            _, digest, blob = message
            try:
                planner = pickle.loads(blob)()
                planner.warmup()
                self.planners[digest] = planner
                return ("registered", digest, None)
            except Exception as error:
                return ("registered", digest, repr(error))
        _, bid, digest, tasks, offset = message
        solve = partial(solve_task, self.planners[digest])
        solved = claim_and_solve(self.shared, bid, self.ident, solve, tasks, offset)
        return ("done", bid, [(k, _picklable(value)) for k, value in solved])


def _picklable(value: Any) -> Any:
    if isinstance(value, Failure):
        try:
            pickle.dumps(value.error)
        except Exception:
            return Failure(RuntimeError(repr(value.error)))
    return value
