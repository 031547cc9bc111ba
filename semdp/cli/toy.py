"""``semdp-toy``: the self-paced Lagrangian toy problem (thesis §2.5.1, Fig. 2.1).

Runs every method of :class:`solvers.self_paced_lagrangian.SelfPacedLagrangianToy` from ``x0``
and writes into the Hydra run directory:

* ``fig_2_1.png`` -- the four panels of Fig. 2.1: (a) f and c over x with the feasible set shaded,
  (b) x, (c) f(x) and (d) c(x) over the iterations, plain vs self-paced Lagrangian;
* ``summary.json`` -- final x, f, c, lambda, iterations and "reached the global optimum" per method.

Examples::

    semdp-toy                                   # x0 = -5, about a second
    semdp-toy x0=0.3 solver.threshold_rule=literal
    semdp-toy -m x0=-6,-5,4.9                   # joblib launcher, 2 jobs
    semdp-toy -m experiment=toy                 # 21 starts over the three intervals of §2.5.1
"""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path
from typing import Any

import hydra
import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.errors import InstantiationException
from hydra.utils import instantiate
from matplotlib.figure import Figure
from omegaconf import DictConfig, OmegaConf

from semdp.cli.one_line import discard_set_up, run_app
from semdp.paths import CONF_DIR
from solvers.self_paced_lagrangian import (
    GLOBAL_OPTIMUM_VALUE,
    DynamicsResult,
    IpoptResult,
    SelfPacedLagrangianToy,
)

logger = logging.getLogger(__name__)

FIGURE_NAME = "fig_2_1.png"
SUMMARY_NAME = "summary.json"
PLAIN_COLOUR, SELF_PACED_COLOUR, OPTIMUM_COLOUR = "tab:orange", "tab:blue", "tab:green"


def _method_summary(result: DynamicsResult | IpoptResult) -> dict[str, Any]:
    summary: dict[str, Any] = {
        "x": result.x,
        "f": result.f,
        "c": result.c,
        "lagrange_multiplier": result.lagrange_multiplier,
        "iterations": result.iterations,
        "reached_global_optimum": result.reached_global,
    }
    if isinstance(result, IpoptResult):
        summary["success"] = result.success
        if result.method == "ipopt_homotopy":
            summary["x_path"] = result.x_path.tolist()
    else:
        summary["final_threshold"] = result.threshold
    return summary


def plot_figure_2_1(
    solver: SelfPacedLagrangianToy,
    plain: DynamicsResult,
    self_paced: DynamicsResult,
    x0: float,
    path: Path,
) -> None:
    """Write the four panels of Fig. 2.1 to ``path``.

    Args:
        solver: provides ``f`` and ``c`` (CasADi functions) for panel (a).
        plain: result of :meth:`SelfPacedLagrangianToy.lagrangian`.
        self_paced: result of :meth:`SelfPacedLagrangianToy.self_paced`.
        x0: the common start (marked in panel a).
        path: PNG file to write.
    """
    figure = Figure(figsize=(13, 9.5), layout="constrained")
    (ax_fc, ax_x), (ax_f, ax_c) = figure.subplots(2, 2)
    visited = np.concatenate([plain.x_history, self_paced.x_history, [x0]])
    low = min(-2.5 * math.pi, float(visited.min()) - 0.5)
    high = max(2.5 * math.pi, float(visited.max()) + 0.5)
    grid = np.linspace(low, high, 1200)
    f_grid = np.asarray(solver.problem.objective(grid.reshape(1, -1))).ravel()
    c_grid = np.asarray(solver.problem.constraint(grid.reshape(1, -1))).ravel()

    # (a) f and c over x, feasible set c(x) <= 0 shaded
    ax_fc.plot(grid, f_grid, color="black", label=r"$f(x) = (x-\pi)^2/50$")
    ax_fc.plot(grid, c_grid, color="tab:red", label=r"$c(x) = -5\cos x$")
    ax_fc.fill_between(
        grid,
        -5.5,
        5.5,
        where=c_grid <= 0.0,
        color="tab:green",
        alpha=0.12,
        label=r"feasible: $c(x) \leq 0$",
    )
    ax_fc.axhline(0.0, color="grey", linewidth=0.6)
    for x_star in (math.pi / 2, 3 * math.pi / 2):
        ax_fc.plot(
            [x_star],
            [GLOBAL_OPTIMUM_VALUE],
            marker="*",
            markersize=14,
            color=OPTIMUM_COLOUR,
            linestyle="none",
        )
    ax_fc.plot(
        [],
        [],
        marker="*",
        markersize=12,
        color=OPTIMUM_COLOUR,
        linestyle="none",
        label=r"global optima $\pi/2$, $3\pi/2$",
    )
    ax_fc.axvline(x0, color="grey", linestyle=":", label=f"start $x_0$ = {x0:g}")
    ax_fc.plot([plain.x], [plain.f], "o", color=PLAIN_COLOUR, label="Lagrangian: final")
    ax_fc.plot(
        [self_paced.x], [self_paced.f], "s", color=SELF_PACED_COLOUR, label="SP Lagrangian: final"
    )
    ax_fc.set(xlabel="x", ylim=(-5.5, 9.5), title="(a) objective and constraint")
    ax_fc.legend(loc="upper center", fontsize=8, ncol=3)

    iterations = np.arange(plain.x_history.size)
    panels = (
        (ax_x, "x_history", "x", "(b) x over iterations", (math.pi / 2, 3 * math.pi / 2)),
        (ax_f, "f_history", "f(x)", "(c) f(x) over iterations", (GLOBAL_OPTIMUM_VALUE,)),
        (ax_c, "c_history", "c(x)", "(d) c(x) over iterations", (0.0,)),
    )
    for axis, attribute, ylabel, title, references in panels:
        axis.plot(iterations, getattr(plain, attribute), color=PLAIN_COLOUR, label="Lagrangian")
        axis.plot(
            np.arange(self_paced.x_history.size),
            getattr(self_paced, attribute),
            color=SELF_PACED_COLOUR,
            label="SP Lagrangian",
        )
        for value in references:
            axis.axhline(value, color=OPTIMUM_COLOUR, linestyle="--", linewidth=1.0)
        axis.set(xlabel="iteration", ylabel=ylabel, title=title)
    ax_x.plot([], [], color=OPTIMUM_COLOUR, linestyle="--", label=r"global optimum ($x^*$, $f^*$)")
    ax_c.plot(
        np.arange(self_paced.threshold_history.size),
        self_paced.threshold_history,
        color=SELF_PACED_COLOUR,
        linestyle=":",
        label="SP threshold $d_i$",
    )
    ax_c.plot([], [], color=OPTIMUM_COLOUR, linestyle="--", label="target $c = 0$")
    for axis in (ax_x, ax_c):
        axis.legend(loc="best", fontsize=8)
    ax_f.legend(loc="best", fontsize=8)
    figure.suptitle(
        "Self-paced Lagrangian on min (x-pi)^2/50 s.t. -5 cos x <= 0 "
        f"(thesis Fig. 2.1), x0 = {x0:g}, threshold rule: {solver.threshold_rule}"
    )
    figure.savefig(path, dpi=110)


def format_table(summary: dict[str, Any]) -> str:
    """Plain-text table of the per-method results in ``summary``."""
    header = f"{'method':<20} {'x':>11} {'f':>11} {'c':>10} {'lambda':>9} {'iters':>6}  global"
    lines = [f"x0 = {summary['x0']:g}   f* = pi^2/200 = {summary['f_star']:.8f}", header]
    for name, row in summary["methods"].items():
        lines.append(
            f"{name:<20} {row['x']:>11.6f} {row['f']:>11.8f} {row['c']:>10.2e} "
            f"{row['lagrange_multiplier']:>9.5f} {row['iterations']:>6d}  "
            f"{'yes' if row['reached_global_optimum'] else 'no'}"
        )
    return "\n".join(lines)


def run(cfg: DictConfig, output_dir: Path) -> dict[str, Any]:
    """Run every method from ``cfg.x0`` and write the figure and summary into ``output_dir``.

    Args:
        cfg: composed ``conf/toy.yaml`` (keys ``x0``, ``solver``).
        output_dir: existing directory (the Hydra run directory under ``semdp-toy``).

    Returns:
        The summary written to ``summary.json``.

    Raises:
        ValueError: on an invalid start or solver setting (names the parameter).
    """
    start = time.perf_counter()
    try:
        solver: SelfPacedLagrangianToy = instantiate(cfg.solver)
    except InstantiationException as error:  # the constructor's ValueError, without Hydra's frame
        if isinstance(error.__cause__, ValueError):
            raise ValueError(f"solver.{error.__cause__}") from None
        raise
    x0 = cfg.x0
    results = solver.solve_all(x0)
    other_rule = "literal" if solver.threshold_rule == "tighten" else "tighten"
    results[f"self_paced_{other_rule}"] = solver.self_paced(x0, threshold_rule=other_rule)
    summary: dict[str, Any] = {
        "x0": float(x0),
        "f_star": GLOBAL_OPTIMUM_VALUE,
        "threshold_rule": solver.threshold_rule,
        "thresholds": list(solver.schedule),
        "methods": {name: _method_summary(result) for name, result in results.items()},
        # Only the toy's own keys: a budget preset shared with the training apps may add others.
        "config": {"x0": float(x0), "solver": OmegaConf.to_container(cfg.solver, resolve=True)},
    }
    plain, self_paced = results["lagrangian"], results["self_paced"]
    assert isinstance(plain, DynamicsResult) and isinstance(self_paced, DynamicsResult)
    output_dir.mkdir(parents=True, exist_ok=True)
    plot_figure_2_1(solver, plain, self_paced, float(x0), output_dir / FIGURE_NAME)
    summary["wall_time_s"] = time.perf_counter() - start
    (output_dir / SUMMARY_NAME).write_text(json.dumps(summary, indent=2) + "\n")
    return summary


@hydra.main(config_path=str(CONF_DIR), config_name="toy", version_base="1.3")
def app(cfg: DictConfig) -> float:
    """The Hydra app; returns the self-paced Lagrangian's final f (a sweeper's objective)."""
    output_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        summary = run(cfg, output_dir)
    except ValueError as error:  # bad input: one line naming the key, nothing left behind
        discard_set_up(output_dir, f"{HydraConfig.get().job.name}.log")
        raise SystemExit(f"semdp-toy: {error}") from None
    print(format_table(summary))
    print(
        f"wrote {output_dir / FIGURE_NAME} and {output_dir / SUMMARY_NAME} "
        f"({summary['wall_time_s']:.1f} s)"
    )
    return float(summary["methods"]["self_paced"]["f"])


def main() -> None:
    """Console entry point (``semdp-toy``): the Hydra app, every error in one line."""
    run_app(app, "semdp-toy")


if __name__ == "__main__":
    main()
