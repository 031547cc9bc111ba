"""Short plans of one robot rolled out from one state: each plan holds one action for some
steps, then brakes (the model's backup), optionally after a common first action.

The motion is the model's own law (:meth:`~semdp.embedded.robot_models.PointModel.advance`
under :meth:`~semdp.embedded.robot_models.PointModel.command`, the backup's
:meth:`~semdp.embedded.robot_models.PointModel.brake_command`), written once in
:class:`~semdp.embedded.robot_models.Ops` arithmetic. ``kernel="python"`` steps it on floats,
plan by plan; ``"compiled"`` traces it once with CasADi symbols into a function of the state,
the held command, the hold and the first command, and ``"native"`` runs that function as C
compiled once per machine (:mod:`solvers.native`). The traced expressions are the float path's,
operation by operation (``fmin``/``fmax`` for ``min``/``max``, the same libm ``cos``/``sin``,
model constants in products kept as parameters, the hold's switch a select), so every kernel
gives the same numbers bit for bit (tests/test_moving_gremlins.py checks them against
``model.step`` and each other). The moving-gremlin certificate
(:mod:`semdp.embedded.moving_certificate`) and the exit from inside a region
(:mod:`semdp.embedded.exit_planning`) roll out dozens of plans at every step they are needed.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from semdp.embedded.robot_models import FLOAT_OPS, Ops, RobotModel, RobotState, symbolic_ops
from solvers.native import native_function

#: ``kernel=`` of :func:`rollout` (the safety filter's ``kernel`` option).
KERNELS: tuple[str, ...] = ("python", "compiled", "native")
#: The compiled kernels' lengths are multiples of this many steps.
STEP_BLOCK = 32


def rollout(model: RobotModel, state: RobotState, first: np.ndarray | None,
            actions: np.ndarray, holds: np.ndarray, steps: int, with_yaw: bool = False,
            kernel: str = "native") -> np.ndarray:
    """Root positions ``(n, steps, 2)`` after each env step of ``n`` plans from ``state``:
    ``first`` (if given) for one step, then ``actions[i]`` for ``holds[i]`` steps, then the
    backup until ``steps`` steps have passed. ``with_yaw``: poses ``(n, steps, 3)``, the
    heading after each step too."""
    if kernel not in KERNELS:
        raise ValueError(f"rollout kernel must be one of {KERNELS}, got {kernel!r}")
    actions = np.asarray(actions, dtype=np.float64).reshape(-1, 2)
    holds = np.asarray(holds).reshape(-1)
    commands = [model.command(a) for a in actions]
    start = (state.x, state.y, state.vx, state.vy, state.yaw, state.w)
    opening = None if first is None else model.command(np.asarray(first, dtype=np.float64))
    if kernel == "python":
        out = np.array([_poses(model, start, opening, c, int(h), steps, FLOAT_OPS)
                        for c, h in zip(commands, holds, strict=True)], dtype=np.float64)
    else:
        out = _kernel(model, steps, opening is not None, kernel == "native")(
            start, opening, commands, holds)[:, :3 * steps]
    return out.reshape(len(actions), steps, 3)[:, :, :3 if with_yaw else 2]


def _poses(model: RobotModel, state: tuple[Any, ...], opening: tuple[Any, Any] | None,
           held: tuple[Any, Any], hold: Any, steps: int, ops: Ops) -> list[Any]:
    """``x, y, yaw`` after each of ``steps`` env steps of one plan, flat, in ``ops``'
    arithmetic; ``hold`` a number, or a CasADi symbol (the held or the braking command then
    chosen per step by ``if_else``)."""
    out: list[Any] = []
    offset = 0 if opening is None else 1
    for k in range(steps):
        if k < offset:
            assert opening is not None
            command = opening
        elif isinstance(hold, int | np.integer):
            command = held if k - offset < hold else model.brake_command(*state, ops)
        else:
            brake = model.brake_command(*state, ops)
            command = (ca.if_else(hold > k - offset, held[0], brake[0]),
                       ca.if_else(hold > k - offset, held[1], brake[1]))
        state = model.advance(*state, command, ops)
        out += [state[0], state[1], state[4]]
    return out


class _RolloutKernel:
    """One plan's poses as a CasADi function of ``(state, held command, hold, first command,
    constants)``, evaluated plan by plan through zero-copy buffers."""

    def __init__(self, model: RobotModel, steps: int, opening: bool, native: bool) -> None:
        ops, symbols, values = symbolic_ops()
        state, held, hold, first = (ca.SX.sym(n, d) for n, d in (("s", 6), ("a", 2),
                                                                  ("k", 1), ("f", 2)))
        poses = _poses(model, tuple(state[i] for i in range(6)),
                       (first[0], first[1]) if opening else None, (held[0], held[1]), hold,
                       steps, ops)
        function = ca.Function(f"plan_rollout_{type(model).__name__}_{steps}_{int(opening)}",
                               [state, held, hold, first, ca.vertcat(*symbols)],
                               [ca.vertcat(*poses)])
        if native:
            function = native_function(function) or function
        self.args = [np.zeros(6), np.zeros(2), np.zeros(1), np.zeros(2),
                     np.array(values, dtype=np.float64)]
        self.out = np.zeros(3 * steps)
        self.buffer, self.evaluate = function.buffer()
        for i, arg in enumerate(self.args):
            self.buffer.set_arg(i, memoryview(arg))
        self.buffer.set_res(0, memoryview(self.out))

    def __call__(self, state: tuple[float, ...], opening: tuple[float, float] | None,
                 commands: list[tuple[float, float]], holds: np.ndarray) -> np.ndarray:
        s, held, hold, first, _ = self.args
        s[:] = state
        if opening is not None:
            first[:] = opening
        out = np.empty((len(commands), len(self.out)))
        for i, (command, k) in enumerate(zip(commands, holds, strict=True)):
            held[:] = command
            hold[0] = k
            self.evaluate()
            out[i] = self.out
        return out


_KERNELS: dict[tuple[type, int, bool, bool], _RolloutKernel] = {}


def _kernel(model: RobotModel, steps: int, opening: bool, native: bool) -> _RolloutKernel:
    """The kernel of ``model``'s robot class for rollouts of up to ``steps`` steps, built on
    first use and shared by the filters of this process (a model's constants are its robot
    class's). One kernel per :data:`STEP_BLOCK` steps: a rollout's first steps do not depend
    on its later ones, so longer ones are cut, and a kept plan, one step shorter at each step,
    needs no function of its own per length."""
    steps = STEP_BLOCK * math.ceil(steps / STEP_BLOCK)
    key = (type(model), steps, opening, native)
    if key not in _KERNELS:
        _KERNELS[key] = _RolloutKernel(model, steps, opening, native)
    return _KERNELS[key]
