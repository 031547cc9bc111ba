"""The toy problem of thesis §2.5.1 (Eq. 2.11, Fig. 2.1) as a CasADi model.

The problem::

    min_x f(x) = (x - pi)^2 / 50    s.t.    c(x) = -5 cos(x) <= d

is built once, symbolically: ``f``, ``c`` and their gradients are ``cs.Function`` objects and
the IPOPT solver is one parametric ``nlpsol`` with the threshold ``d`` as its parameter. For
``d = 0`` the feasible set is the union of the intervals ``[-pi/2 + 2k pi, pi/2 + 2k pi]``; the
global minimisers are ``pi/2`` and ``3 pi/2`` (``f* = pi^2/200``) and a start in
``[-5pi/2, -3pi/2]`` has the local minimiser ``-3pi/2`` (``f = 25 pi^2/200 ~ 1.2337``) in its own
component.
"""

from __future__ import annotations

import math

import casadi as cs

#: Optimal value of Eq. 2.11 (attained at x = pi/2 and x = 3 pi/2).
GLOBAL_OPTIMUM_VALUE: float = math.pi**2 / 200.0
#: Value at the local minimiser -3 pi/2 of the component [-5 pi/2, -3 pi/2].
LOCAL_OPTIMUM_VALUE: float = 25.0 * math.pi**2 / 200.0


class ToyProblem:
    """CasADi model of Eq. 2.11: ``f``, ``c``, their gradients and a parametric IPOPT solver.

    Attributes:
        objective: ``cs.Function`` x -> f(x).
        constraint: ``cs.Function`` x -> c(x).
        terms: ``cs.Function`` x -> (f, c, df/dx, dc/dx), all from CasADi's AD.
        nlp_solver: ``nlpsol`` for ``min f(x) s.t. c(x) - d <= 0`` with parameter ``d``.
    """

    def __init__(self, ipopt_options: dict[str, object] | None = None) -> None:
        x_sym = cs.SX.sym("x")
        d_sym = cs.SX.sym("d")
        f_sym = (x_sym - cs.pi) ** 2 / 50.0
        c_sym = -5.0 * cs.cos(x_sym)
        self.objective = cs.Function("objective", [x_sym], [f_sym], ["x"], ["f"])
        self.constraint = cs.Function("constraint", [x_sym], [c_sym], ["x"], ["c"])
        self.terms = cs.Function(
            "terms",
            [x_sym],
            [f_sym, c_sym, cs.gradient(f_sym, x_sym), cs.gradient(c_sym, x_sym)],
            ["x"],
            ["f", "c", "df", "dc"],
        )
        options: dict[str, object] = {
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.tol": 1e-12,
            "ipopt.constr_viol_tol": 1e-10,
            "print_time": False,
        }
        options.update(ipopt_options or {})
        nlp = {"x": x_sym, "p": d_sym, "f": f_sym, "g": c_sym - d_sym}
        self.nlp_solver = cs.nlpsol("toy_nlp", "ipopt", nlp, options)

    def evaluate(self, x: float) -> tuple[float, float, float, float]:
        """Return ``(f, c, df/dx, dc/dx)`` at ``x``."""
        f, c, df, dc = self.terms(x)
        return float(f), float(c), float(df), float(dc)

    def solve(
        self, x_init: float, threshold: float, lam_init: float = 0.0
    ) -> tuple[float, float, int, bool]:
        """One IPOPT solve of ``min f s.t. c <= threshold`` from ``x_init``.

        Returns:
            ``(x, lam, iterations, success)``.
        """
        solution = self.nlp_solver(x0=x_init, p=threshold, lbg=-cs.inf, ubg=0.0, lam_g0=lam_init)
        stats = self.nlp_solver.stats()
        return (
            float(solution["x"]),
            float(solution["lam_g"]),
            int(stats.get("iter_count", 0)),
            bool(stats.get("success", False)),
        )
