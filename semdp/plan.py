"""``semdp-plan``: plan one trajectory, print its certificate and draw it (SPEC §0, §2.2).

Example::

    semdp-plan start=[0,0] subgoal=[2,1] obstacles=[[1,0.3],[0.4,-0.8]] backend=ipopt

Writes ``plan.png`` (obstacles with their eps' circles, waypoints, subgoal, certificate) and
``plan.json`` (the result) into the Hydra run directory and prints their paths.
"""

from __future__ import annotations

import json
from pathlib import Path

import hydra
import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from semdp.paths import CONF_DIR
from solvers.planner import PlanResult, SafeTrajectoryPlanner

FIGURE_NAME = "plan.png"
RESULT_NAME = "plan.json"


def result_to_dict(result: PlanResult) -> dict[str, object]:
    """A JSON-friendly dictionary of a :class:`PlanResult`."""
    out: dict[str, object] = {}
    for key, value in vars(result).items():
        if isinstance(value, np.ndarray):
            out[key] = value.tolist()
        elif isinstance(value, float) and not np.isfinite(value):
            out[key] = str(value)
        else:
            out[key] = value
    return out


def plot_plan(
    result: PlanResult,
    subgoal: np.ndarray,
    obstacles: np.ndarray,
    clearance: float,
    path: Path,
) -> None:
    """Draw obstacles (radius filled, eps' + r dashed), waypoints, start, subgoal, certificate."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    fig, ax = plt.subplots(figsize=(6.4, 6.0))
    for row in obstacles:
        radius = float(row[2]) if len(row) > 2 else 0.0
        if radius > 0:
            ax.add_patch(Circle(row[:2], radius, color="tab:purple", alpha=0.6))
        ax.add_patch(Circle(row[:2], clearance + radius, fill=False, ls="--", color="tab:purple"))
        ax.plot(row[0], row[1], "x", color="tab:purple")
    points = result.waypoints
    ax.plot(points[:, 0], points[:, 1], "-o", ms=3, color="tab:green", label="waypoints")
    ax.plot(*points[0], "o", ms=9, color="tab:red", label="start")
    ax.plot(*subgoal, "*", ms=14, color="tab:orange", label="subgoal")
    text = (
        f"{result.backend}: {result.status}\n"
        f"feasible={result.feasible} fallback={result.fallback} escape={result.escape_mode}\n"
        f"min clearance: waypoints {result.min_clearance:.4f} m, "
        f"continuous {result.min_clearance_continuous:.4f} m (eps'={clearance})\n"
        f"||x_N - g||={np.sqrt(result.objective):.4f} m, {result.solve_time_s * 1e3:.1f} ms"
    )
    ax.text(0.01, 0.99, text, transform=ax.transAxes, va="top", fontsize=8,
            bbox={"facecolor": "white", "alpha": 0.85})
    everything = np.vstack([points, subgoal[None, :], *(o[None, :2] for o in obstacles)])
    low = everything.min(axis=0) - clearance - 0.5
    high = everything.max(axis=0) + clearance + 0.5
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(cfg: DictConfig, output_dir: Path) -> PlanResult:
    """Build the planner from ``cfg.planner`` (``cfg.backend`` overrides its backend) and plan."""
    overrides = {} if cfg.get("backend") is None else {"backend": str(cfg.backend)}
    planner: SafeTrajectoryPlanner = instantiate(cfg.planner, **overrides)
    obstacles = OmegaConf.to_container(cfg.obstacles, resolve=True) if cfg.obstacles else []
    result = planner.plan(list(cfg.start), list(cfg.subgoal), obstacles)
    output_dir.mkdir(parents=True, exist_ok=True)
    (output_dir / RESULT_NAME).write_text(json.dumps(result_to_dict(result), indent=2) + "\n")
    if cfg.get("plot", True):
        array = np.asarray(obstacles, dtype=float).reshape(-1, np.shape(obstacles)[1]
                                                           if len(obstacles) else 2)
        plot_plan(result, np.asarray(cfg.subgoal, dtype=float), array, planner.clearance,
                  output_dir / FIGURE_NAME)
    return result


@hydra.main(config_path=str(CONF_DIR), config_name="plan", version_base="1.3")
def main(cfg: DictConfig) -> None:
    """Hydra entry point of ``semdp-plan``."""
    output_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        result = run(cfg, output_dir)
    except ValueError as error:
        raise SystemExit(f"semdp-plan: {error}") from None
    print(result.summary())
    print(f"wrote {output_dir / RESULT_NAME}")
    if cfg.get("plot", True):
        print(f"wrote {output_dir / FIGURE_NAME}")


if __name__ == "__main__":
    main()
