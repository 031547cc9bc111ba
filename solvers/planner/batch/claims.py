"""The work sharing of :func:`solvers.planner.batch.planning.plan_batch`: one page of claims.

A page of shared memory (a temporary file mapped by every process) holds the batch id and one
claim byte per problem. Each process walks the problems from its own starting offset and solves
a problem only after writing its id into a free claim byte, so the work balances one problem at a
time. Two processes that claim the same byte at the same instant both solve it (a harmless
duplicate; the first result is kept); no problem is ever left out, because a process skips only
problems someone else has claimed. Every problem is solved as ``plan(start, subgoal, obstacles,
warm_start=False)`` solves it (:func:`solve_task`), certificate included (thesis §3.5.2), and an
exception is kept as that problem's result (:func:`attempt`) for the caller to re-raise in
problem order.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import Any, Protocol

#: Problems per round of claims (larger batches are shared in several rounds).
CAPACITY = 4096
#: Bytes before the claims: the int64 id of the batch being claimed (0: none).
HEADER = 8
#: Claim value of the process that shares the batch out; helpers use 2, 3, ...
MAIN_ID = 1
#: Size of the shared page.
SIZE = HEADER + CAPACITY

Task = tuple[Any, Any, Any]


class BatchSolver(Protocol):
    """What a helper builds from a factory: a planner it can warm up and solve with."""

    def warmup(self) -> object:
        """Build every compiled solver now."""
        ...

    def plan(self, start: Any, subgoal: Any, obstacles: Any = None,
             warm_start: bool = True) -> Any:
        """Plan one problem."""
        ...


def solve_task(solver: BatchSolver, task: Task) -> Any:
    """``plan(start, subgoal, obstacles, warm_start=False)`` for one (start, subgoal, obstacles)
    problem of a batch."""
    start, subgoal, obstacles = task
    return solver.plan(start, subgoal, obstacles, warm_start=False)


def attempt(solve: Callable[[Task], Any], task: Task) -> Any:
    """``solve(task)``, or the exception it raised wrapped as a :class:`Failure`."""
    try:
        return solve(task)
    except Exception as error:  # re-raised by the caller in problem order
        return Failure(error)


class Failure:
    """An exception raised while solving one problem (kept apart from results)."""

    def __init__(self, error: Exception) -> None:
        self.error = error


def is_failure(value: object) -> bool:
    """Whether a batch result is a :class:`Failure`."""
    return isinstance(value, Failure)


def failure_error(value: object) -> Exception:
    """The exception of a :class:`Failure`."""
    assert isinstance(value, Failure)
    return value.error


def open_batch(shared: Any, bid: int, n: int) -> None:
    """Clear the claims of ``n`` problems and publish batch ``bid`` (helpers start claiming)."""
    shared[HEADER : HEADER + n] = bytes(n)
    struct.pack_into("<q", shared, 0, bid)


def close_batch(shared: Any) -> None:
    """Withdraw the batch: late helpers stop claiming."""
    struct.pack_into("<q", shared, 0, 0)


def claim(shared: Any, k: int, ident: int) -> bool:
    """Claim problem ``k`` for process ``ident``; False when someone else already has."""
    if shared[HEADER + k]:
        return False
    shared[HEADER + k] = ident
    return True


def owner(shared: Any, k: int) -> int:
    """The id of the process that claimed problem ``k`` (0: nobody)."""
    return int(shared[HEADER + k])


def claim_and_solve(shared: Any, bid: int, ident: int, solve: Callable[[Task], Any],
                    tasks: Sequence[Task], offset: int) -> list[tuple[int, Any]]:
    """A helper's share of batch ``bid``: walk the problems from ``offset``, solve each one it
    claims, stop when the batch is withdrawn; ``[(k, result or Failure), ...]``."""
    solved = []
    n = len(tasks)
    for step in range(n):
        k = (offset + step) % n
        if struct.unpack_from("<q", shared, 0)[0] != bid:
            break
        if claim(shared, k, ident):
            solved.append((k, attempt(solve, tasks[k])))
    return solved
