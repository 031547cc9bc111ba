"""``plan_batch``: several independent problems at once, shared with helper processes.

Every problem is solved as ``planner.plan(start, subgoal, obstacles, warm_start=False)`` solves
it, certificate and fallback included, so the plans equal those of a loop of ``plan`` calls:
exactly for IPOPT and LM, to about 1e-8 m for SCP (OSQP carries rounding state from one QP to
the next, so SCP plans depend slightly on the problems solved before, in a loop too). Speed
comes from a second core (the helper processes of :mod:`solvers.planner.batch.pool`, sharing
the problems through :mod:`solvers.planner.batch.claims`); the measurements behind the default are
in docs/planner.md, "Benchmark".

This module works on any planner with ``settings``, ``memory``, ``plan``, ``warmup`` and a
``from_settings`` class method (:class:`BatchPlanner`); the planner module does not import it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from functools import partial
from typing import Any, Protocol

import numpy as np

from solvers.planner.batch.claims import failure_error, is_failure, solve_task
from solvers.planner.batch.pool import default_workers, factory_blob, get_pool
from solvers.planner.result import PlanResult
from solvers.planner.warm_start import WarmStartMemory

logger = logging.getLogger(__name__)

#: Work of a problem for the batch timing, in solver iterations: its iterations plus this (the
#: preparation, initial guesses and certificate cost about two iterations).
BATCH_WORK_PER_PROBLEM = 2

Task = tuple[object, object, object]


class BatchPlanner(Protocol):
    """What :func:`plan_batch` needs of a planner (``SafeTrajectoryPlanner`` has it)."""

    settings: Any
    memory: WarmStartMemory

    @classmethod
    def from_settings(cls, settings: Any) -> BatchPlanner:
        """A fresh planner with these settings (what a helper process builds)."""
        ...

    def plan(self, start: Any, subgoal: Any, obstacles: Any = None,
             warm_start: bool = True) -> PlanResult:
        """Plan one problem."""
        ...

    def warmup(self) -> object:
        """Build every compiled solver now."""
        ...


def batch_config(planner: BatchPlanner) -> tuple[bytes, bytes]:
    """The pickled factory of ``planner``'s configuration sent to the helpers, and its digest."""
    return factory_blob(partial(type(planner).from_settings, planner.settings))


def plan_batch(
    planner: BatchPlanner,
    starts: Sequence[Sequence[float]] | np.ndarray,
    subgoals: Sequence[Sequence[float]] | np.ndarray,
    obstacles_list: Sequence[object],
    workers: int | None = None,
) -> list[PlanResult]:
    """Plan several independent problems (e.g. one per vectorised environment).

    The plans equal those of a loop of ``planner.plan(..., warm_start=False)`` (see the module
    docstring). Afterwards the planner's warm-start memory holds the last problem, as after the
    loop.

    The problems are shared with ``workers - 1`` helper processes, which claim them one at a
    time. Threads cannot do this: CasADi keeps the GIL while IPOPT or an LM kernel runs (a
    thread pool measured 0.9-1.0x the loop). The helpers start on the first call that wants them
    and build each planner configuration once; until they are ready the batch runs here alone,
    so call :func:`start_batch_workers` to start them ahead. The gain needs an idle core: when
    every core is busy with other jobs sharing can be slower than the loop, hence the measured
    default below. A lockstep LM variant (one mapped CasADi call and one block-diagonal banded
    solve per iteration for all problems) was measured no faster than the loop and was dropped.

    Args:
        planner: The planner (its settings are sent to the helpers).
        starts: (B, 2) start positions.
        subgoals: (B, 2) subgoals.
        obstacles_list: B obstacle arrays ((m, 2) or (m, 3); None or empty for none).
        workers: Processes solving, this one included. None (default): up to
            ``min(2, usable CPUs)``, sharing or not by measurement, per planner configuration
            and batch size: both ways are tried, then the one with the lower running mean of
            wall time per unit of work (solver iterations) is used, and every 8th batch tries
            the other again. An explicit ``workers > 1`` always shares; 1 solves the problems
            one after the other here.

    Returns:
        One certified :class:`PlanResult` per problem, in order.

    Raises:
        ValueError: Mismatched shapes, ``workers < 1``, or a problem ``plan`` rejects (the
            first such problem's error).
    """
    starts_arr = np.asarray(starts, dtype=float)
    subgoals_arr = np.asarray(subgoals, dtype=float)
    if starts_arr.ndim != 2 or starts_arr.shape[1] != 2:
        raise ValueError(f"starts must have shape (B, 2), got {starts_arr.shape}")
    if subgoals_arr.shape != starts_arr.shape:
        raise ValueError(
            f"subgoals must have the same shape as starts {starts_arr.shape}, "
            f"got {subgoals_arr.shape}"
        )
    if len(obstacles_list) != len(starts_arr):
        raise ValueError(
            f"obstacles_list must have one entry per start ({len(starts_arr)}), "
            f"got {len(obstacles_list)}"
        )
    count = default_workers() if workers is None else workers
    if int(count) != count or count < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    tasks: list[Task] = list(zip(starts_arr, subgoals_arr, obstacles_list, strict=True))
    share = count > 1 and len(tasks) > 1
    key = None
    if share and workers is None:  # measured choice (see HelperPool.choose_shared)
        key = (batch_config(planner)[1], len(tasks))
        share = get_pool().choose_shared(key)
    tic = time.perf_counter()
    shared = _plan_shared(planner, tasks, int(count)) if share else None
    if shared is None:
        results = [solve_task(planner, task) for task in tasks]
    else:
        for value in shared:
            if is_failure(value):
                raise failure_error(value)
        start, subgoal = starts_arr[-1], subgoals_arr[-1]
        planner.memory.remember(start, start + (subgoal - start), shared[-1].waypoints)
        results = shared
    if key is not None:
        work = sum(r.iterations + BATCH_WORK_PER_PROBLEM for r in results)
        get_pool().record(key, shared is not None, time.perf_counter() - tic, work)
    return results


def start_batch_workers(
    planner: BatchPlanner, workers: int | None = None, timeout: float = 60.0
) -> int:
    """Start the helper processes of :func:`plan_batch` now and wait until they are ready.

    Args:
        planner: The planner whose configuration the helpers build.
        workers: As in :func:`plan_batch` (helpers: ``workers - 1``).
        timeout: Seconds to wait at most.

    Returns:
        The number of helpers ready to solve this planner's problems.
    """
    count = default_workers() if workers is None else int(workers)
    if count <= 1:
        return 0
    pool = get_pool()
    blob, digest = batch_config(planner)
    with pool.lock:
        return pool.wait_ready(count - 1, digest, blob, timeout)


def _plan_shared(planner: BatchPlanner, tasks: list[Task], count: int) -> list | None:
    """Solve ``tasks`` here and in the helper processes; None when no helper is ready."""
    try:
        pool = get_pool()
    except OSError as error:  # no shared memory: solve here
        logger.warning("planner batch helpers unavailable: %r", error)
        return None
    if not pool.lock.acquire(blocking=False):  # another thread is using the helpers
        return None
    try:
        blob, digest = batch_config(planner)
        helpers = pool.prepare(count - 1, digest, blob)
        if not helpers:
            return None
        # plain lists pickle several times faster than small arrays; same values
        wire = [(s.tolist(), g.tolist(), o.tolist() if isinstance(o, np.ndarray) else o)
                for s, g, o in tasks]
        return pool.run(partial(solve_task, planner), tasks, wire, helpers, digest)
    finally:
        pool.lock.release()
