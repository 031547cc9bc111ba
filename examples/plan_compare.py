"""Solve one planning problem with IPOPT and with Levenberg-Marquardt, print what each plan
satisfies (Eqs. 3.3-3.7) and draw both (thesis §3.5.2; docs/planner.md, "Compare backends on
one problem").

    python examples/plan_compare.py            # writes plan_compare.png here
"""

from pathlib import Path

from semdp.reporting.plan_plots import plot_comparison
from solvers.planner import compare_backends

comparison = compare_backends(start=[0, 0], subgoal=[2.5, 1],
                              obstacles=[[1, 0.3], [0.4, -0.8], [1.8, 1.2]],
                              backends=["ipopt", "lm"])
print(comparison.table())
for row in comparison.rows:
    print(f"{row.name}: reached subgoal {row.reached_subgoal}, h_smooth {row.smoothness:.3f} "
          f"(budget {row.smoothness_budget}), clearance certified {row.feasible}")
plot_comparison(comparison, Path("plan_compare.png"))
