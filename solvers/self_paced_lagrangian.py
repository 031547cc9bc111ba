"""Self-paced Lagrangian on the toy problem of thesis §2.5.1 (Eq. 2.11, Fig. 2.1, Alg. 1).

The problem ``min (x - pi)^2 / 50 s.t. -5 cos(x) <= d`` and its CasADi/IPOPT model are in
:mod:`solvers.toy_problem`; the results in :mod:`solvers.toy_results`; the threshold curriculum
in :mod:`solvers.threshold_schedule`. This module holds the methods compared in Fig. 2.1 (one
:class:`SelfPacedLagrangianToy` holds the shared settings) and re-exports the names its users
import from here (``conf/toy.yaml``'s ``_target_`` names this module's class):

* :meth:`~SelfPacedLagrangianToy.lagrangian` -- primal-dual dynamics on ``L = f + lam (c - d)``
  (Eqs. 2.4-2.5 with ``d = 0``): Adam on ``x``, dual ascent on ``lam >= 0`` every
  ``lambda_update_every`` steps.
* :meth:`~SelfPacedLagrangianToy.self_paced` -- the same dynamics with the threshold curriculum
  ``D = {2^(N-i) | i = 0..M}`` followed by the target 0 (Eqs. 2.8-2.10, 2.12, Alg. 1), with two
  readings of the threshold rule (:data:`THRESHOLD_RULES`).
* :meth:`~SelfPacedLagrangianToy.ipopt_direct`, :meth:`~SelfPacedLagrangianToy.ipopt_homotopy` and
  :meth:`~SelfPacedLagrangianToy.global_reference` -- exact solves with IPOPT: directly at ``d = 0``
  (local), warm-started through the thresholds (the exact self-paced homotopy), and multi-start.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from solvers.scalar_adam import ScalarAdam
from solvers.threshold_schedule import THRESHOLD_RULES, ThresholdSchedule, threshold_schedule
from solvers.toy_problem import GLOBAL_OPTIMUM_VALUE, LOCAL_OPTIMUM_VALUE, ToyProblem
from solvers.toy_results import DynamicsResult, FloatArray, IpoptResult, frozen_array
from solvers.validation import check_choice, check_int, check_positive, check_real

__all__ = [
    "GLOBAL_OPTIMUM_VALUE",
    "LAMBDA_OPTIMIZERS",
    "LOCAL_OPTIMUM_VALUE",
    "THRESHOLD_RULES",
    "DynamicsResult",
    "FloatArray",
    "IpoptResult",
    "SelfPacedLagrangianToy",
    "ToyProblem",
]

logger = logging.getLogger(__name__)

#: Multiplier updates. ``"sgd"``: Eq. 2.10, ``lam <- max(0, lam + lr_lambda (c(x) - d_i))``.
#: ``"adam"``: Adam ascent on ``lam`` with learning rate ``lr_lambda``, projected onto ``lam >= 0``.
LAMBDA_OPTIMIZERS: tuple[str, ...] = ("sgd", "adam")


class SelfPacedLagrangianToy:
    """Plain vs self-paced Lagrangian on Eq. 2.11, plus the IPOPT references.

    Config keys in ``conf/toy.yaml`` equal these argument names.

    Args:
        lr_x: Adam learning rate for ``x`` (decays exponentially to ``lr_x * lr_decay``).
        lr_lambda: multiplier step: the constant ``beta`` of Eq. 2.10 (``lambda_optimizer="sgd"``)
            or Adam's learning rate (``"adam"``, decays like ``lr_x``).
        lambda_init: initial multiplier (>= 0).
        lambda_optimizer: one of :data:`LAMBDA_OPTIMIZERS`.
        lambda_update_every: x updates per multiplier update (the "lower frequency" of §2.4.2).
        n_iterations: number of x updates.
        lr_decay: final learning-rate multiplier in (0, 1]; 1 keeps the rates constant.
        adam_beta1, adam_beta2: Adam's moment decay rates.
        initial_exponent: N of Eq. 2.12.
        num_thresholds: M of Eq. 2.12 (>= 0).
        threshold_rule: one of :data:`THRESHOLD_RULES`.
        stationarity_tol: "tighten" rule: a stage is solved when ``c <= d_i``,
            ``|df + lam dc| <= tol`` and ``|lam (c - d_i)| <= tol``.
        multistart_points: number of IPOPT starts spread over ``multistart_range``.
        multistart_range: interval ``(low, high)`` of the multi-start grid.
        global_tol: ``|f - f*|`` below which a result counts as the global optimum.
        feasibility_tol: ``c(x)`` above which a result counts as infeasible.

    Raises:
        ValueError: on any invalid argument, naming it.
    """

    def __init__(
        self,
        lr_x: float = 0.05,
        lr_lambda: float = 1e-3,
        lambda_init: float = 1.0,
        lambda_optimizer: str = "sgd",
        lambda_update_every: int = 10,
        n_iterations: int = 10_000,
        lr_decay: float = 1e-3,
        adam_beta1: float = 0.9,
        adam_beta2: float = 0.99,
        initial_exponent: int = 3,
        num_thresholds: int = 8,
        threshold_rule: str = "tighten",
        stationarity_tol: float = 1e-2,
        multistart_points: int = 41,
        multistart_range: tuple[float, float] | list[float] = (-3 * math.pi, 3 * math.pi),
        global_tol: float = 1e-3,
        feasibility_tol: float = 1e-4,
    ) -> None:
        self.lr_x = check_positive("lr_x", lr_x)
        self.lr_lambda = check_positive("lr_lambda", lr_lambda)
        self.lambda_init = check_real("lambda_init", lambda_init)
        if self.lambda_init < 0.0:
            raise ValueError(f"lambda_init must be >= 0, got {lambda_init!r}")
        self.lambda_optimizer = check_choice(
            "lambda_optimizer", lambda_optimizer, LAMBDA_OPTIMIZERS
        )
        self.lambda_update_every = check_int("lambda_update_every", lambda_update_every, 1)
        self.n_iterations = check_int("n_iterations", n_iterations, 1)
        self.lr_decay = check_positive("lr_decay", lr_decay)
        if self.lr_decay > 1.0:
            raise ValueError(f"lr_decay must be in (0, 1], got {lr_decay!r}")
        for name, value in (("adam_beta1", adam_beta1), ("adam_beta2", adam_beta2)):
            if not 0.0 <= check_real(name, value) < 1.0:
                raise ValueError(f"{name} must be in [0, 1), got {value!r}")
        self.adam_beta1, self.adam_beta2 = float(adam_beta1), float(adam_beta2)
        self.schedule = threshold_schedule(initial_exponent, num_thresholds)
        self.initial_exponent, self.num_thresholds = int(initial_exponent), int(num_thresholds)
        self.threshold_rule = check_choice("threshold_rule", threshold_rule, THRESHOLD_RULES)
        self.stationarity_tol = check_positive("stationarity_tol", stationarity_tol)
        self.multistart_points = check_int("multistart_points", multistart_points, 1)
        if len(multistart_range) != 2:
            raise ValueError(f"multistart_range must be (low, high), got {multistart_range!r}")
        low = check_real("multistart_range[0]", multistart_range[0])
        high = check_real("multistart_range[1]", multistart_range[1])
        if not low < high:
            raise ValueError(f"multistart_range must satisfy low < high, got {multistart_range!r}")
        self.multistart_range = (low, high)
        self.global_tol = check_positive("global_tol", global_tol)
        self.feasibility_tol = check_positive("feasibility_tol", feasibility_tol)
        self.problem = ToyProblem()

    # ------------------------------------------------------------------ helpers
    def reached_global(self, f: float, c: float) -> bool:
        """Whether ``(f, c)`` is the global optimum within ``global_tol`` and feasible."""
        return abs(f - GLOBAL_OPTIMUM_VALUE) <= self.global_tol and c <= self.feasibility_tol

    # ------------------------------------------------------------------ dynamics
    def lagrangian(self, x0: float) -> DynamicsResult:
        """Plain Lagrangian primal-dual dynamics from ``x0`` (threshold 0 throughout)."""
        return self._dynamics(x0, schedule=(0.0,), rule="tighten", method="lagrangian")

    def self_paced(self, x0: float, threshold_rule: str | None = None) -> DynamicsResult:
        """Self-paced Lagrangian (Alg. 1 on Eq. 2.11) from ``x0``.

        Args:
            x0: start.
            threshold_rule: overrides the instance's rule (one of :data:`THRESHOLD_RULES`).
        """
        rule = self.threshold_rule if threshold_rule is None else threshold_rule
        rule = check_choice("threshold_rule", rule, THRESHOLD_RULES)
        return self._dynamics(x0, schedule=self.schedule, rule=rule, method=f"self_paced_{rule}")

    def _dynamics(
        self, x0: float, schedule: tuple[float, ...], rule: str, method: str
    ) -> DynamicsResult:
        x = check_real("x0", x0)
        lam = self.lambda_init
        x_optimizer = ScalarAdam(self.lr_x, self.adam_beta1, self.adam_beta2)
        lambda_optimizer = ScalarAdam(self.lr_lambda, self.adam_beta1, self.adam_beta2)
        curriculum = ThresholdSchedule(
            schedule, rule, index=0 if rule == "tighten" else len(schedule) - 1
        )
        threshold = curriculum.current
        f, c, df, dc = self.problem.evaluate(x)
        history = {"x": [x], "f": [f], "c": [c], "lam": [lam], "d": [threshold]}
        for step in range(self.n_iterations):
            lr_scale = self.lr_decay ** (step / self.n_iterations)
            if step % self.lambda_update_every == 0:
                # "tighten": a stage is solved when its KKT conditions hold within the tolerance
                stage_solved = (
                    c <= threshold
                    and abs(df + lam * dc) <= self.stationarity_tol
                    and abs(lam * (c - threshold)) <= self.stationarity_tol
                )
                previous, threshold = threshold, curriculum.select(c, stage_solved)
                if rule == "tighten" and threshold != previous:
                    logger.debug("step %d: threshold tightened to %g", step, threshold)
                violation = c - threshold
                if self.lambda_optimizer == "sgd":  # Eq. 2.10
                    lam = max(0.0, lam + self.lr_lambda * violation)
                else:  # Adam ascent on lam, projected
                    lam = max(0.0, lam + lambda_optimizer.step(violation, lr_scale))
            x -= x_optimizer.step(df + lam * dc, lr_scale)
            f, c, df, dc = self.problem.evaluate(x)
            history["x"].append(x)
            history["f"].append(f)
            history["c"].append(c)
            history["lam"].append(lam)
            history["d"].append(threshold)
        return DynamicsResult(
            method=method,
            x=x,
            f=f,
            c=c,
            lagrange_multiplier=lam,
            threshold=threshold,
            iterations=self.n_iterations,
            reached_global=self.reached_global(f, c),
            x_history=frozen_array(history["x"]),
            f_history=frozen_array(history["f"]),
            c_history=frozen_array(history["c"]),
            lambda_history=frozen_array(history["lam"]),
            threshold_history=frozen_array(history["d"]),
        )

    # ------------------------------------------------------------------ IPOPT
    def _ipopt_result(
        self,
        method: str,
        x: float,
        lam: float,
        iterations: int,
        success: bool,
        thresholds: list[float],
        x_path: list[float],
    ) -> IpoptResult:
        f, c, _, _ = self.problem.evaluate(x)
        return IpoptResult(
            method=method,
            x=x,
            f=f,
            c=c,
            lagrange_multiplier=lam,
            iterations=iterations,
            success=success,
            reached_global=self.reached_global(f, c),
            thresholds=frozen_array(thresholds),
            x_path=frozen_array(x_path),
        )

    def ipopt_direct(self, x0: float) -> IpoptResult:
        """IPOPT on ``c(x) <= 0`` from ``x0``: a local solution (the component of the start)."""
        x_start = check_real("x0", x0)
        x, lam, iterations, success = self.problem.solve(x_start, 0.0)
        return self._ipopt_result("ipopt_direct", x, lam, iterations, success, [0.0], [x])

    def ipopt_homotopy(self, x0: float) -> IpoptResult:
        """Exact self-paced homotopy: IPOPT warm-started through ``2^N, ..., 2^(N-M), 0``.

        Each stage solves Eq. 2.8 for its threshold from the previous stage's solution and
        multiplier. Stage thresholds above ``max c = 5`` make the constraint inactive, so the first
        stage returns the unconstrained minimiser ``pi``; the tightening stages then move the
        solution outwards along the boundary ``c(x) = d`` to ``pi/2`` or ``3 pi/2``.
        """
        x = check_real("x0", x0)
        lam, total_iterations, all_success = 0.0, 0, True
        x_path: list[float] = []
        for threshold in self.schedule:
            x, lam, iterations, success = self.problem.solve(x, threshold, lam)
            total_iterations += iterations
            all_success &= success
            x_path.append(x)
        return self._ipopt_result(
            "ipopt_homotopy", x, lam, total_iterations, all_success, list(self.schedule), x_path
        )

    def global_reference(self) -> IpoptResult:
        """Multi-start IPOPT at ``d = 0``: the best of ``multistart_points`` local solutions."""
        starts = np.linspace(*self.multistart_range, self.multistart_points)
        best: tuple[float, float, float, bool] | None = None
        total_iterations = 0
        x_path: list[float] = []
        for start in starts:
            x, lam, iterations, success = self.problem.solve(float(start), 0.0)
            total_iterations += iterations
            x_path.append(x)
            f, c, _, _ = self.problem.evaluate(x)
            if success and c <= self.feasibility_tol and (best is None or f < best[0]):
                best = (f, x, lam, success)
        if best is None:
            raise RuntimeError("multi-start IPOPT found no feasible solution")
        _, x, lam, success = best
        return self._ipopt_result(
            "ipopt_multistart",
            x,
            lam,
            total_iterations,
            success,
            [0.0] * len(starts),
            x_path,
        )

    def solve_all(self, x0: float) -> dict[str, DynamicsResult | IpoptResult]:
        """Every method from ``x0``: plain and self-paced dynamics, IPOPT direct/homotopy/global."""
        check_real("x0", x0)
        return {
            "lagrangian": self.lagrangian(x0),
            "self_paced": self.self_paced(x0),
            "ipopt_direct": self.ipopt_direct(x0),
            "ipopt_homotopy": self.ipopt_homotopy(x0),
            "ipopt_multistart": self.global_reference(),
        }
