"""``plan_batch`` with helper processes (solvers/planner/batch/): the
plans equal a loop of ``plan`` calls for every backend, including empty, over-full and escape-mode
problems; bad inputs, a dead helper and pickling."""

from __future__ import annotations

import os
import pickle
import signal
import time

import numpy as np
import pytest

from solvers.planner import (
    LMSettings,
    ProblemSettings,
    SafeTrajectoryPlanner,
    plan_batch,
    random_problems,
    start_batch_workers,
)
from solvers.planner.batch import pool as batch_module
from solvers.planner.batch.planning import batch_config

VARIANTS = {
    "ipopt": {"backend": "ipopt"},
    "lm": {"backend": "lm"},
    "lm_adaptive": {"backend": LMSettings(adaptive=True)},
    "scp": {"backend": "scp"},
}
MAX_OBSTACLES = 4  # few compiled slot counts: quick to build, and easy to exceed


def _wait_gone(pid: int) -> None:
    for _ in range(100):
        try:
            if os.waitpid(pid, os.WNOHANG)[0] == pid:
                return
        except ChildProcessError:
            return
        time.sleep(0.05)


@pytest.fixture(scope="module", autouse=True)
def _stop_helpers():
    yield
    batch_module.shutdown_pool()


@pytest.fixture(scope="module")
def planners() -> dict[str, SafeTrajectoryPlanner]:
    return {
        name: SafeTrajectoryPlanner(**kwargs, problem=ProblemSettings(max_obstacles=MAX_OBSTACLES))
        for name, kwargs in VARIANTS.items()
    }


def _problems() -> tuple[list, list, list]:
    problems = random_problems(9, seed=11, radius_share=0.3)
    starts = [p.start for p in problems]
    subgoals = [p.subgoal for p in problems]
    obstacles = [p.obstacles for p in problems]
    rng = np.random.default_rng(3)
    starts += [np.array([0.0, 0.0]), np.array([1.0, -1.0]), np.array([2.0, 2.0])]
    subgoals += [np.array([1.5, 0.5]), np.array([2.5, 0.0]), np.array([0.5, 2.5])]
    obstacles += [
        np.zeros((0, 2)),  # no obstacle
        np.array([1.0, -1.0]) + rng.uniform(-2.5, 2.5, size=(3 * MAX_OBSTACLES, 2)) * [1, 1]
        + np.array([[0.8, 0.0]] * (3 * MAX_OBSTACLES)),  # more than max_obstacles
        np.array([[2.3, 2.0], [4.0, 4.0]]),  # the start is inside eps': escape mode
    ]
    return starts, subgoals, obstacles


def _slow_here(monkeypatch, delay: float = 0.02) -> None:
    """Make this process slow so the helper certainly claims problems of the batch."""
    solve = SafeTrajectoryPlanner.plan

    def slow(self, *args, **kwargs):
        time.sleep(delay)
        return solve(self, *args, **kwargs)

    monkeypatch.setattr(SafeTrajectoryPlanner, "plan", slow)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_plan_batch_with_helpers_equals_loop(planners, variant, monkeypatch) -> None:
    planner = planners[variant]
    assert start_batch_workers(planner, workers=2) == 1
    starts, subgoals, obstacles = _problems()
    loop = [
        planner.plan(s, g, o, warm_start=False)
        for s, g, o in zip(starts, subgoals, obstacles, strict=True)
    ]
    loop_previous = planner.memory.previous
    pool = batch_module.get_pool()
    before = pool.solved_by_helpers
    _slow_here(monkeypatch)
    batch = plan_batch(planner, starts, subgoals, obstacles, workers=2)
    assert pool.solved_by_helpers > before  # the helper did take part
    assert len(batch) == len(loop)
    assert batch[-3].n_considered == 0 and batch[-2].n_considered == MAX_OBSTACLES
    assert batch[-1].escape_mode
    # SCP: OSQP keeps rounding state between QPs, so plans depend on what was solved before at
    # the 1e-8 level (in a loop too); the other backends are exactly reproducible
    atol = 1e-6 if variant == "scp" else 1e-9
    for k, (a, b) in enumerate(zip(batch, loop, strict=True)):
        np.testing.assert_allclose(a.waypoints, b.waypoints, atol=atol, err_msg=str(k))
        assert (a.feasible, a.fallback, a.escape_mode, a.reached_subgoal) == (
            b.feasible, b.fallback, b.escape_mode, b.reached_subgoal
        ), k
        if variant != "scp":
            assert (a.status, a.iterations) == (b.status, b.iterations), k
        if a.feasible and not a.escape_mode:
            assert a.min_clearance >= planner.clearance - 1e-9, k
    for got, want in zip(planner.memory.previous, loop_previous, strict=True):
        np.testing.assert_allclose(got, want, atol=atol)


def test_plan_batch_reraises_the_first_bad_problem(planners, monkeypatch) -> None:
    planner = planners["lm"]
    assert start_batch_workers(planner, workers=2) == 1
    starts, subgoals, obstacles = _problems()
    obstacles[5] = [[1.0, 1.0, -0.2]]
    obstacles[9] = [[1.0, 1.0, float("nan")]]
    _slow_here(monkeypatch)
    with pytest.raises(ValueError, match="radii must be >= 0"):
        plan_batch(planner, starts, subgoals, obstacles, workers=2)
    # the helpers still work afterwards
    monkeypatch.undo()
    starts, subgoals, obstacles = _problems()
    batch = plan_batch(planner, starts, subgoals, obstacles, workers=2)
    assert all(r.feasible or r.escape_mode for r in batch)


def test_plan_batch_survives_a_dead_helper(planners) -> None:
    planner = planners["lm_adaptive"]
    assert start_batch_workers(planner, workers=2) == 1
    starts, subgoals, obstacles = _problems()
    loop = [planner.plan(s, g, o, warm_start=False)
            for s, g, o in zip(starts, subgoals, obstacles, strict=True)]
    helper = batch_module.get_pool().helpers[0]
    os.kill(helper.process.pid, signal.SIGKILL)
    _wait_gone(helper.process.pid)
    batch = plan_batch(planner, starts, subgoals, obstacles, workers=2)
    for a, b in zip(batch, loop, strict=True):
        np.testing.assert_allclose(a.waypoints, b.waypoints, atol=1e-9)
    assert start_batch_workers(planner, workers=2) == 1  # a new helper replaces it


def test_plan_batch_workers_argument_and_pickling(planners) -> None:
    planner = planners["lm"]
    starts, subgoals, obstacles = _problems()
    with pytest.raises(ValueError, match="workers"):
        plan_batch(planner, starts, subgoals, obstacles, workers=0)
    pool = batch_module.get_pool()
    before = pool.solved_by_helpers
    alone = plan_batch(planner, starts, subgoals, obstacles, workers=1)
    assert pool.solved_by_helpers == before
    clone = pickle.loads(pickle.dumps(planner))
    assert clone.solver.kernels == {} and clone.memory.previous is not None
    again = plan_batch(clone, starts, subgoals, obstacles)
    for a, b in zip(alone, again, strict=True):
        np.testing.assert_allclose(a.waypoints, b.waypoints, atol=1e-9)


def test_plan_batch_default_measures_which_way_is_faster(planners, monkeypatch) -> None:
    planner = planners["ipopt"]
    monkeypatch.setattr(batch_module, "usable_cpus", lambda: 2)  # default: 2 processes
    assert start_batch_workers(planner) == 1
    starts, subgoals, obstacles = _problems()
    pool = batch_module.get_pool()
    key = (batch_config(planner)[1], len(starts))
    pool.timings.pop(key, None)
    _slow_here(monkeypatch)
    before = pool.solved_by_helpers
    plan_batch(planner, starts, subgoals, obstacles)  # first: shared
    assert pool.solved_by_helpers > before
    shared_sums, alone_sums, batches = pool.timings[key]
    assert min(shared_sums) > 0 and alone_sums is None and batches == 1
    before = pool.solved_by_helpers
    plan_batch(planner, starts, subgoals, obstacles)  # then: here alone
    assert pool.solved_by_helpers == before and min(pool.timings[key][1]) > 0
    # afterwards the faster way, and every EXPLORE_EVERY-th batch the other one
    pool.timings[key] = [[2.0, 1.0], [1.0, 1.0], 2]  # [seconds, work]: here alone is faster
    ways = [pool.choose_shared(key) for _ in range(2 * batch_module.EXPLORE_EVERY)]
    assert ways.count(True) == 2 and ways[batch_module.EXPLORE_EVERY - 3]
    pool.timings[key] = [[1.0, 1.0], [2.0, 1.0], 0]
    assert pool.choose_shared(key)
