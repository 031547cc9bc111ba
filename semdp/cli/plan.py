"""``semdp-plan``: plan one problem, print the certificate and draw it (thesis §3.5.2).

Examples::

    semdp-plan start=[0,0] subgoal=[2,1] obstacles=[[1,0.3],[0.4,-0.8]] backend=ipopt
    semdp-plan backends=[ipopt,lm,lm_adaptive,scp] start=[0,0] subgoal=[2,1] \\
        obstacles=[[1,0.3],[0.4,-0.8]]

One planner (``planner=<conf/planner name>``; ``backend=ipopt|lm|scp`` replaces its ``backend``
node by that backend's defaults, ``planner.backend.<knob>=`` sets one of its knobs): writes
``plan.png`` (obstacles with their eps' circles, waypoints, subgoal, certificate) and
``plan.json`` (the result). Compare mode (``backends=[...]``, each a ``conf/planner`` name
composed by Hydra, every ``planner.<key>=`` override applied to each): the same problem solved by
every planner, written as ``compare.png`` (the plans overlaid), ``compare.json`` and
``compare.csv`` (one row per planner), and the table printed. Everything goes into the Hydra run
directory. Bad input ends the run with one line on stderr and exit status 1.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import hydra
import numpy as np
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from hydra.errors import HydraException, InstantiationException
from hydra.utils import instantiate
from omegaconf import DictConfig, ListConfig, OmegaConf

from semdp.cli.one_line import discard_set_up, run_app
from semdp.paths import CONF_DIR
from semdp.reporting.plan_plots import plot_comparison, plot_plan
from solvers.planner import Comparison, Planner, PlanResult, compare
from solvers.planner.compare import COLUMNS as COMPARE_COLUMNS
from solvers.planner.problem.preparation import validate_obstacles

FIGURE_NAME = "plan.png"
RESULT_NAME = "plan.json"
COMPARE_FIGURE = "compare.png"
COMPARE_JSON = "compare.json"
COMPARE_CSV = "compare.csv"
#: The config group whose options ``backends=[...]`` names.
PLANNER_GROUP = "planner"


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


def _obstacles(cfg: DictConfig) -> np.ndarray:
    """``cfg.obstacles`` as an (m, 3) array ``[x, y, r]``; ValueError when malformed."""
    value = cfg.get("obstacles")
    if OmegaConf.is_config(value):
        value = OmegaConf.to_container(value, resolve=True)
    centres, radii = validate_obstacles(value if value else None)
    return np.column_stack([centres, radii])


def _instantiate_planner(node: DictConfig, name: str, **overrides: Any) -> Planner:
    """The planner of a composed ``conf/planner`` node; a bad setting is a one-line
    ValueError naming the planner."""
    label = f"planner {name}" if name else "planner"
    try:
        planner = instantiate(node, **overrides)
    except InstantiationException as error:  # the constructor's ValueError, without Hydra's frame
        if isinstance(error.__cause__, ValueError):
            raise ValueError(f"{label}: {error.__cause__}") from None
        raise ValueError(f"{label}: {str(error).splitlines()[0]}") from None
    if not isinstance(planner, Planner):
        raise ValueError(f"{label} is not a planner (no plan()): {planner!r}")
    return planner


def run(cfg: DictConfig, output_dir: Path) -> PlanResult:
    """Build the planner from ``cfg.planner`` (``cfg.backend``, a backend name, replaces its
    backend node by that backend's default settings) and plan."""
    overrides = {} if cfg.get("backend") is None else {"backend": str(cfg.backend)}
    obstacles = _obstacles(cfg)
    planner = _instantiate_planner(cfg.planner, "", **overrides)
    result = planner.plan(list(cfg.start), list(cfg.subgoal), obstacles)
    output_dir.mkdir(parents=True, exist_ok=True)
    (output_dir / RESULT_NAME).write_text(json.dumps(result_to_dict(result), indent=2) + "\n")
    if cfg.get("plot", True):
        plot_plan(result, np.asarray(cfg.subgoal, dtype=float), obstacles, planner.clearance,
                  output_dir / FIGURE_NAME)
    return result


def planner_overrides(task_overrides: Sequence[str]) -> list[str]:
    """The command-line overrides of planner keys, without the ``planner.`` prefix
    (``planner.problem.continuous=true`` -> ``problem.continuous=true``), which compare mode
    applies to every
    planner; the group choice ``planner=...`` is not one of them."""
    prefix = f"{PLANNER_GROUP}."
    return [o[len(prefix):] for o in task_overrides if o.startswith(prefix)]


def compose_planner(name: str, overrides: Sequence[str] = ()) -> DictConfig:
    """The ``conf/planner/<name>.yaml`` node composed by Hydra with ``overrides`` of its keys
    (``continuous=true``), inside the running ``semdp-plan`` app (its config search path) or,
    from Python, from ``conf/``.

    Raises:
        ValueError: ``name`` is not a ``conf/planner`` option (the message lists them), or an
            override does not apply to it.
    """
    hydra_instance = GlobalHydra.instance()
    if hydra_instance.is_initialized():
        return _compose_planner(hydra_instance, name, overrides)
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return _compose_planner(GlobalHydra.instance(), name, overrides)


def _compose_planner(
    hydra_instance: GlobalHydra, name: str, overrides: Sequence[str]
) -> DictConfig:
    options = sorted(o for o in hydra_instance.config_loader().get_group_options(PLANNER_GROUP)
                     if not o.startswith("_"))
    if name not in options:
        raise ValueError(f"unknown planner {name!r} in backends; options: {options}")
    try:
        cfg = compose(config_name=f"{PLANNER_GROUP}/{name}",
                      overrides=[f"{PLANNER_GROUP}.{item}" for item in overrides])
    except HydraException as error:  # an override that does not apply to this planner
        reason = str(error).splitlines()[0]
        if error.__cause__ is not None:
            reason += f" ({str(error.__cause__).splitlines()[0]})"
        raise ValueError(f"planner {name}: {reason}") from None
    node = cfg[PLANNER_GROUP]
    assert isinstance(node, DictConfig)
    return node


def _backend_names(value: object) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if isinstance(value, ListConfig):
        value = OmegaConf.to_container(value, resolve=True)
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise ValueError(
            f"backends must be a non-empty list of conf/planner names, e.g. backends=[ipopt,lm], "
            f"got {value!r}"
        )
    if len(set(value)) != len(value):
        raise ValueError(f"backends lists a planner twice: {value}")
    return list(value)


def run_compare(cfg: DictConfig, output_dir: Path, overrides: Sequence[str] = ()) -> Comparison:
    """Compose and build every planner of ``cfg.backends``, solve the problem with each, and
    write ``compare.json``, ``compare.csv`` and (with ``cfg.plot``) ``compare.png``.

    Args:
        cfg: The composed ``conf/plan.yaml`` (``backends``, ``start``, ``subgoal``,
            ``obstacles``, ``repeats``, ``plot``).
        output_dir: Where the files go (created).
        overrides: ``<key>=<value>`` overrides of planner keys applied to every planner.

    Raises:
        ValueError: A bad backend list, an unknown planner, a bad planner setting or override,
            or malformed start, subgoal or obstacles.
    """
    if cfg.get("backend") is not None:
        raise ValueError("give either backend= (one planner) or backends=[...] (compare), not both")
    names = _backend_names(cfg.backends)
    obstacles = _obstacles(cfg)
    planners = {name: _instantiate_planner(compose_planner(name, overrides), name)
                for name in names}
    comparison = compare(list(cfg.start), list(cfg.subgoal), obstacles, planners=planners,
                         repeats=int(cfg.get("repeats", 3)))
    output_dir.mkdir(parents=True, exist_ok=True)
    payload = {**comparison.to_dict(), "planner_overrides": list(overrides)}
    (output_dir / COMPARE_JSON).write_text(json.dumps(payload, indent=2) + "\n")
    with open(output_dir / COMPARE_CSV, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(COMPARE_COLUMNS))
        writer.writeheader()
        writer.writerows(comparison.records())
    if cfg.get("plot", True):
        plot_comparison(comparison, output_dir / COMPARE_FIGURE)
    return comparison


def _refuse(error: ValueError) -> SystemExit:
    """One line for bad input; the output directory Hydra set up for it is removed."""
    discard_set_up(HydraConfig.get().runtime.output_dir, f"{HydraConfig.get().job.name}.log")
    return SystemExit(f"semdp-plan: {error}")


@hydra.main(config_path=str(CONF_DIR), config_name="plan", version_base="1.3")
def app(cfg: DictConfig) -> None:
    """The Hydra app of ``semdp-plan``."""
    output_dir = Path(HydraConfig.get().runtime.output_dir)
    if cfg.get("backends") is not None:
        overrides = planner_overrides(HydraConfig.get().overrides.task)
        try:
            comparison = run_compare(cfg, output_dir, overrides)
        except ValueError as error:
            raise _refuse(error) from None
        print(comparison.table())
        names = [COMPARE_JSON, COMPARE_CSV, *([COMPARE_FIGURE] if cfg.get("plot", True) else [])]
        for name in names:
            print(f"wrote {output_dir / name}")
        return
    try:
        result = run(cfg, output_dir)
    except ValueError as error:
        raise _refuse(error) from None
    print(result.summary())
    print(f"wrote {output_dir / RESULT_NAME}")
    if cfg.get("plot", True):
        print(f"wrote {output_dir / FIGURE_NAME}")


def main() -> None:
    """Console entry point (``semdp-plan``): the Hydra app, every error in one line."""
    run_app(app, "semdp-plan")


if __name__ == "__main__":
    main()
