"""CasADi functions as native code (solvers/native.py): the same floats as CasADi's virtual
machine, compiled once into the cache, and the virtual machine where no compiler is found."""

from __future__ import annotations

import logging

import casadi as ca
import numpy as np
import pytest

from solvers import native
from solvers.planner import LMSettings, SafeTrajectoryPlanner, random_problems
from solvers.planner.backends import lm as lm_module
from solvers.planner.backends import native_lm
from solvers.planner.backends.banded_least_squares import BandedKernel, levenberg_marquardt
from solvers.planner.backends.native_lm import NativeBandedKernel

pytestmark = pytest.mark.skipif(native.compiler() is None, reason="needs a C compiler")


def _function() -> ca.Function:
    """Operations whose rounding depends on their order (sums of products, sqrt, fmax)."""
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2)
    out = ca.vertcat(ca.sqrt(ca.dot(x, x) + p[0]) * x[0] + x[1] * x[2] * p[1],
                     ca.fmax(0.0, p[0] - ca.norm_2(x[:2])) ** 2 + ca.sin(x[2]) / (1.0 + p[1]))
    return ca.Function("order_sensitive", [x, p], [out, ca.jacobian(out, x)])


def test_native_code_gives_the_virtual_machines_floats_bit_for_bit(tmp_path) -> None:
    vm = _function()
    compiled = native.native_function(vm, tmp_path)
    assert compiled is not None and compiled.class_name() == "External"
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, p = rng.normal(size=3) * 10.0 ** rng.integers(-3, 3), rng.uniform(0.0, 2.0, 2)
        for a, b in zip(vm(x, p), compiled(x, p), strict=True):
            assert np.array_equal(np.asarray(a), np.asarray(b))


def test_a_function_is_compiled_once_and_then_loaded_from_the_cache(tmp_path, monkeypatch) -> None:
    native.native_function(_function(), tmp_path)
    (library,) = tmp_path.glob("order_sensitive_*.so")
    stamp = library.stat().st_mtime_ns

    def refuse(*args, **kwargs):
        raise AssertionError("compiled again")

    monkeypatch.setattr(native, "_compile", refuse)
    again = native.native_function(_function(), tmp_path)
    assert again is not None and library.stat().st_mtime_ns == stamp
    assert sorted(p.name for p in tmp_path.iterdir()) == [library.name]  # no scratch left


def test_without_a_compiler_the_caller_keeps_the_virtual_machine(tmp_path, monkeypatch,
                                                                 caplog) -> None:
    monkeypatch.setenv("CC", "no-such-compiler-here")
    monkeypatch.setattr(native, "_warned", set())
    with caplog.at_level(logging.WARNING, logger="solvers.native"):
        assert native.native_function(_function(), tmp_path) is None
    assert "no C compiler" in caplog.text and not list(tmp_path.iterdir())
    plans = SafeTrajectoryPlanner(backend=LMSettings(native=True))
    assert plans.solver.kernel(2).step.class_name() == "SXFunction"  # the VM's: same numbers


def _adversarial_problems() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(start, subgoal, obstacles) where LM works hardest: a narrow gap, a subgoal inside an
    obstacle, a start on an obstacle's clearance edge, an obstacle right on the straight line."""
    gap = np.array([[0.6, 0.26, 0.2], [0.6, -0.26, 0.2]])
    inside = np.array([[0.9, 0.0, 0.3], [0.4, 0.5, 0.15]])
    edge = np.array([[0.3, 0.0, 0.3 - 1e-6], [1.0, 0.4, 0.2]])
    line = np.array([[0.7, 0.0, 0.25]])
    origin = np.zeros(2)
    return [(origin, np.array([1.3, 0.0]), gap), (origin, np.array([0.9, 0.05]), inside),
            (origin, np.array([1.2, 0.3]), edge), (origin, np.array([1.5, 0.0]), line),
            (np.array([0.2, 0.0]), np.array([-1.0, 0.2]), edge)]


def _problems() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    problems = random_problems(40, seed=5, radius_share=0.3)
    return [(p.start, p.subgoal, p.obstacles) for p in problems] + _adversarial_problems()


def _same_plans(plain: SafeTrajectoryPlanner, fast: SafeTrajectoryPlanner) -> None:
    for start, subgoal, obstacles in _problems():
        for warm_start in (False, True):
            a = plain.plan(start, subgoal, obstacles, warm_start=warm_start)
            b = fast.plan(start, subgoal, obstacles, warm_start=warm_start)
            assert np.array_equal(a.waypoints, b.waypoints)
            assert np.array_equal(a.velocities, b.velocities)
            assert (a.status, a.iterations, a.feasible) == (b.status, b.iterations, b.feasible)


def test_the_lm_planner_plans_the_same_with_native_kernels(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("SOLVERS_NATIVE_CACHE", str(tmp_path))
    monkeypatch.setattr(lm_module, "native_banded_kernel", lambda *args: None)  # loop in Python
    plain = SafeTrajectoryPlanner(backend=LMSettings(adaptive=True, native=False))
    fast = SafeTrajectoryPlanner(backend=LMSettings(adaptive=True, native=True))
    _same_plans(plain, fast)
    slots = set(fast.solver.kernels)
    assert len(slots) >= 2
    assert all(fast.solver.kernels[n].step.class_name() == "External" for n in slots)
    assert len(list(tmp_path.glob("lm_step_*.so"))) == len(slots)


@pytest.mark.parametrize("adaptive", [False, True])
def test_the_native_lm_iteration_plans_the_python_loops_plans_bit_for_bit(
        tmp_path, monkeypatch, adaptive: bool) -> None:
    monkeypatch.setenv("SOLVERS_NATIVE_CACHE", str(tmp_path))
    plain = SafeTrajectoryPlanner(backend=LMSettings(adaptive=adaptive, native=False))
    fast = SafeTrajectoryPlanner(backend=LMSettings(adaptive=adaptive, native=True))
    _same_plans(plain, fast)
    assert fast.solver.kernels and all(
        isinstance(k, NativeBandedKernel) for k in fast.solver.kernels.values())
    assert len(list(tmp_path.glob("lm_loop_*.so"))) == len(fast.solver.kernels)


def test_the_native_lm_iteration_matches_from_any_start_and_damping(tmp_path,
                                                                     monkeypatch) -> None:
    """Kernel level: the C iteration returns the Python iteration's (z, cost, iterations) for
    random starting points and dampings (failed steps, backtracking and damping changes)."""
    monkeypatch.setenv("SOLVERS_NATIVE_CACHE", str(tmp_path))
    settings = LMSettings(native=True)
    planner = SafeTrajectoryPlanner(backend=settings)
    kernel = planner.solver.kernel(4)
    assert isinstance(kernel, NativeBandedKernel)
    rng = np.random.default_rng(3)
    prep = planner.context.prepare(np.zeros(2), np.array([1.2, 0.2]),
                                   np.array([[0.5, 0.0, 0.2], [0.8, 0.3, 0.15],
                                             [0.3, -0.4, 0.1], [1.0, -0.1, 0.2]]),
                                   reach=planner.solver.selection_reach)
    kernel.p[:] = planner.solver.params(prep, 4, 1.0)
    for _ in range(60):
        z0 = rng.normal(size=kernel.n_var) * 10.0 ** rng.uniform(-3, 0.5)
        damping = 10.0 ** rng.uniform(-6, 2)
        iterations = int(rng.integers(1, 25))
        native_result = kernel.minimise(z0, iterations=iterations, damping=damping)
        python_result = levenberg_marquardt(kernel, z0, iterations=iterations, damping=damping)
        assert np.array_equal(native_result[0], python_result[0])
        assert native_result[1:] == python_result[1:]
        assert kernel.cost_at(z0) == BandedKernel.cost_at(kernel, z0)


def test_without_numpys_blas_the_lm_iteration_stays_in_python(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("SOLVERS_NATIVE_CACHE", str(tmp_path))
    monkeypatch.setattr(native_lm, "_blas", lambda: None)
    kernel = SafeTrajectoryPlanner(backend=LMSettings(native=True)).solver.kernel(2)
    assert type(kernel) is BandedKernel and kernel.step.class_name() == "External"


def test_native_must_be_a_flag() -> None:
    with pytest.raises(ValueError, match="native"):
        LMSettings(native="yes")  # type: ignore[arg-type]
