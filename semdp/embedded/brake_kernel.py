"""The safety filter's certificate compiled: one step's end point, then the braking manoeuvre,
against every cost region, in one CasADi call (the filter of :mod:`semdp.embedded.shield`).

:meth:`SafetyShield.clearance <semdp.embedded.shield.SafetyShield.clearance>` is the smallest
``distance - R`` between the root positions of the manoeuvre and the regions ``[x, y, R]``; in
Python it costs a loop of ``horizon x substeps`` scalar updates per checked action (the
Point's 40 x 2, the Car's 30 x 4), most of the filter's time. :class:`ClearanceKernel` traces
the model's ``brake_points`` once with CasADi symbols
(:class:`~semdp.embedded.robot_models.Ops`) into an SX function of the state after the first
step and the regions, and evaluates it through zero-copy buffers.

Same numbers, not close ones: the traced expressions are the plain path's, operation by
operation (the distance of :mod:`solvers.planner.geometry`, which the plain path evaluates
on NumPy arrays; ``fmin``/``fmax`` for ``min``/``max``; the same libm ``cos``/``sin``; a model
constant in a product of constants kept as a parameter, so that CasADi does not multiply the
constants out first), so the kernel's clearance
equals the plain path's bit for bit (tests/test_brake_kernel.py checks it on random states and
on whole filtered episodes) and the filter takes the same decisions with either. Region counts
are padded to the next power of two with regions far away (one compiled function per count).
With ``native=True`` each function runs as C compiled once per machine (:mod:`solvers.native`:
the same operations in the same order, so the same floats; CasADi's virtual machine where no C
compiler is found).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from semdp.embedded.robot_models import RobotState, symbolic_ops
from solvers.native import native_function
from solvers.planner.geometry import CASADI, length, point_offset

#: A padding region: far from any arena, radius 0 (its gap never the smallest).
FAR = 1.0e9


def compiles(model: Any) -> bool:
    """Whether ``model`` has a braking manoeuvre this kernel can trace (the Point and the Car;
    the Mass stops in two steps, which the plain path does as fast)."""
    return callable(getattr(model, "brake_points", None))


def _build(model: Any, slots: int) -> tuple[ca.Function, np.ndarray]:
    """``clearance(state, regions, constants) -> min gap`` for ``slots`` regions (row-major
    ``[x, y, R]``) and the values of its ``constants`` (the model's :attr:`Ops.const`)."""
    state = ca.SX.sym("s", 6)
    regions = ca.SX.sym("r", 3 * slots)
    ops, symbols, values = symbolic_ops()
    x, y, vx, vy, yaw, w = (state[i] for i in range(6))
    points = [(x, y), *model.brake_points(x, y, vx, vy, yaw, w, ops)]
    gaps = []
    for px, py in points:
        for j in range(slots):
            offset = point_offset(px, py, regions[3 * j], regions[3 * j + 1])
            gaps.append(length(*offset, ops=CASADI) - regions[3 * j + 2])
    function = ca.Function(f"brake_clearance_{slots}", [state, regions, ca.vertcat(*symbols)],
                           [ca.mmin(ca.vertcat(*gaps))])
    return function, np.array(values, dtype=np.float64)


class ClearanceKernel:
    """The compiled :meth:`SafetyShield.clearance` of one robot model (see the module docstring).

    Call it with the state *after* the checked action's step and the regions ``(m, 3)``.
    Not pickled with its compiled functions (a copy rebuilds them on first use);
    :func:`kernel_for` shares one per model class.
    """

    def __init__(self, model: Any, native: bool = False) -> None:
        if not compiles(model):
            raise ValueError(f"{type(model).__name__} has no brake_points() to compile")
        self.model = model
        self.native = bool(native)
        self._slots: dict[int, tuple[Any, ...]] = {}

    def _entry(self, count: int) -> tuple[Any, ...]:
        slots = 1 << max(0, math.ceil(math.log2(max(count, 1))))
        if slots not in self._slots:
            function, constants = _build(self.model, slots)
            if self.native:
                function = native_function(function) or function
            state, regions, out = np.zeros(6), np.full(3 * slots, FAR), np.zeros(1)
            regions[2::3] = 0.0
            buffer, evaluate = function.buffer()
            buffer.set_arg(0, memoryview(state))
            buffer.set_arg(1, memoryview(regions))
            buffer.set_arg(2, memoryview(constants))
            buffer.set_res(0, memoryview(out))
            self._slots[slots] = (buffer, evaluate, state, regions, out, constants)
        return self._slots[slots]

    def __call__(self, s: RobotState, regions: np.ndarray) -> float:
        """Smallest ``distance - R`` over the root at ``s`` and the braking manoeuvre from it."""
        _, evaluate, state, padded, out, _ = self._entry(len(regions))
        state[:] = (s.x, s.y, s.vx, s.vy, s.yaw, s.w)
        flat = np.ascontiguousarray(regions, dtype=np.float64).ravel()
        padded[:len(flat)] = flat
        padded[len(flat):] = FAR
        padded[len(flat) + 2::3] = 0.0
        evaluate()
        return float(out[0])

    def __getstate__(self) -> dict[str, Any]:
        return {"model": self.model, "native": self.native, "_slots": {}}


_KERNELS: dict[tuple[type, bool], ClearanceKernel] = {}


def kernel_for(model: Any, native: bool = False) -> ClearanceKernel:
    """The kernel of ``model``'s robot, shared by the filters of this process (a model's
    constants are its robot class's, so one kernel serves every instance of a model class)."""
    key = (type(model), bool(native))
    if key not in _KERNELS:
        _KERNELS[key] = ClearanceKernel(model, native)
    return _KERNELS[key]
