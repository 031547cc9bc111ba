"""CasADi functions as native code (solvers/native.py): the same floats as CasADi's virtual
machine, compiled once into the cache, and the virtual machine where no compiler is found."""

from __future__ import annotations

import logging

import casadi as ca
import numpy as np
import pytest

from solvers import native
from solvers.planner import LMSettings, SafeTrajectoryPlanner, random_problems

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


def test_the_lm_planner_plans_the_same_with_native_kernels(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("SOLVERS_NATIVE_CACHE", str(tmp_path))
    plain = SafeTrajectoryPlanner(backend=LMSettings(adaptive=True))
    fast = SafeTrajectoryPlanner(backend=LMSettings(adaptive=True, native=True))
    problems = random_problems(40, seed=5, radius_share=0.3)
    for problem in problems:
        a = plain.plan(problem.start, problem.subgoal, problem.obstacles)
        b = fast.plan(problem.start, problem.subgoal, problem.obstacles)
        assert np.array_equal(a.waypoints, b.waypoints)
        assert (a.status, a.iterations, a.feasible) == (b.status, b.iterations, b.feasible)
    slots = set(fast.solver.kernels)
    assert len(slots) >= 2
    assert all(fast.solver.kernels[n].step.class_name() == "External" for n in slots)
    assert len(list(tmp_path.glob("lm_step_*.so"))) == len(slots)


def test_native_must_be_a_flag() -> None:
    with pytest.raises(ValueError, match="native"):
        LMSettings(native="yes")  # type: ignore[arg-type]
