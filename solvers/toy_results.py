"""What the toy problem's methods return (thesis §2.5.1, Fig. 2.1): the Adam primal-dual
dynamics (plain and self-paced Lagrangian, Alg. 1) and the IPOPT solves, with read-only
histories."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def frozen_array(values: list[float] | FloatArray) -> FloatArray:
    """``values`` as a read-only float64 array (the results' histories)."""
    array = np.asarray(values, dtype=np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class DynamicsResult:
    """Outcome of the Adam primal-dual dynamics (plain or self-paced Lagrangian).

    Attributes:
        method: ``"lagrangian"`` or ``"self_paced_<rule>"``.
        x, f, c: final iterate and its objective and constraint values.
        lagrange_multiplier: final ``lam``.
        threshold: the threshold in force at the end (0 when the curriculum finished).
        iterations: number of x updates.
        reached_global: ``|f - f*| <= global_tol`` and ``c <= feasibility_tol``.
        x_history, f_history, c_history, lambda_history, threshold_history: one entry per
            iteration, the initial point first (length ``iterations + 1``).
    """

    method: str
    x: float
    f: float
    c: float
    lagrange_multiplier: float
    threshold: float
    iterations: int
    reached_global: bool
    x_history: FloatArray = field(repr=False)
    f_history: FloatArray = field(repr=False)
    c_history: FloatArray = field(repr=False)
    lambda_history: FloatArray = field(repr=False)
    threshold_history: FloatArray = field(repr=False)


@dataclass(frozen=True)
class IpoptResult:
    """Outcome of an IPOPT solve (direct, homotopy or multi-start).

    Attributes:
        method: ``"ipopt_direct"``, ``"ipopt_homotopy"`` or ``"ipopt_multistart"``.
        x, f, c: solution and its objective and constraint values.
        lagrange_multiplier: IPOPT's multiplier of ``c(x) - d <= 0`` at the last solve.
        iterations: total IPOPT iterations over all solves.
        success: every solve reported ``Solve_Succeeded`` (multi-start: the best one did).
        reached_global: ``|f - f*| <= global_tol`` and ``c <= feasibility_tol``.
        thresholds: threshold ``d`` of each solve (homotopy: the curriculum; multi-start: 0 per
            start).
        x_path: solution of each solve, aligned with ``thresholds`` (multi-start: the starts'
            local solutions).
    """

    method: str
    x: float
    f: float
    c: float
    lagrange_multiplier: float
    iterations: int
    success: bool
    reached_global: bool
    thresholds: FloatArray = field(repr=False)
    x_path: FloatArray = field(repr=False)
