"""Find and load run directories of a sweep (the run-directory contract of docs/design.md).

Fields relied on (all optional; whatever is missing is reported, never fatal):

* ``metrics.json``: ``status`` ("running" | "completed" | "failed"), ``error``, ``label``
  (method label; falls back to ``algo``), ``algo``, ``env``, ``seed``, ``eval.return_mean``,
  ``eval.cost_mean`` and, for the Fig. B.1 sweep, ``tradeoff``: a list of
  ``{"clearance", "return_mean", "cost_mean"}``.
* ``progress.csv``: columns ``env_steps``, ``ep_return``, ``ep_cost`` (empty cell = not measured).
  A Safety-Embedded MDP run counts *high-level* steps there (one per subgoal); its curves are
  put on low-level env steps by multiplying by k, taken from ``metrics.json["semdp"]["k"]`` or,
  for an unfinished run, from ``config.yaml``'s ``env.wrapper.k``.
* ``config.yaml``: ``cost_limit`` (drawn in the cost curves) and, when ``metrics.json`` is
  missing, ``label``, ``algo_name``, ``env_name``, ``seed``, to name an unfinished run.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from semdp.reporting.names import algorithm_name, trained_env

logger = logging.getLogger(__name__)

METRICS_NAME = "metrics.json"
PROGRESS_NAME = "progress.csv"
CONFIG_NAME = "config.yaml"
CURVE_COLUMNS: tuple[str, ...] = ("env_steps", "ep_return", "ep_cost")
UNKNOWN = "unknown"

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TradeoffPoint:
    """One evaluation of a trained policy at a planner clearance ε' (Fig. B.1)."""

    clearance: float
    return_mean: float
    cost_mean: float


@dataclass(frozen=True)
class RunRecord:
    """What the report knows about one run directory.

    Attributes:
        path: the run directory.
        status: ``metrics.json``'s status, or ``"no metrics.json"`` / ``"unreadable metrics.json"``.
        error: error message of a failed run.
        label: method label (``label``, else ``algo``, else ``unknown``).
        env: environment name.
        seed: seed, if known.
        eval_return, eval_cost: final evaluation means (None when absent).
        curves: ``{column: values}`` of ``progress.csv`` (NaN = empty cell); empty when absent.
        tradeoff: Fig. B.1 points, if any.
        problems: human-readable reasons this run is incomplete (empty when fully usable).
        cost_limit: the run's top-level ``cost_limit`` from ``config.yaml``, if any.
        unconstrained: ``config.yaml``'s ``algo`` has no ``cost_limit`` (SAC, PPO, TRPO: the
            top-level limit is not what they were trained with).
    """

    path: Path
    status: str
    error: str | None
    label: str
    env: str
    seed: int | None
    eval_return: float | None
    eval_cost: float | None
    curves: dict[str, FloatArray] = field(repr=False)
    tradeoff: tuple[TradeoffPoint, ...] = ()
    problems: tuple[str, ...] = ()
    cost_limit: float | None = None
    unconstrained: bool = False

    @property
    def has_final_eval(self) -> bool:
        """Completed with a final evaluation: usable in the table."""
        return (
            self.status == "completed"
            and self.eval_return is not None
            and self.eval_cost is not None
        )


def find_run_dirs(root: Path) -> list[Path]:
    """Every directory below ``root`` (inclusive) holding ``metrics.json`` or ``progress.csv``.

    Hydra job directories (with a ``.hydra/`` folder) that hold neither and contain no run
    directory are returned too: they are runs that never wrote anything.
    """
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"not a directory: {root}")
    runs: list[Path] = []
    hydra_jobs: list[Path] = []
    for directory, subdirs, files in os.walk(root):
        subdirs[:] = sorted(d for d in subdirs if d != ".hydra" and d != "checkpoints")
        path = Path(directory)
        if METRICS_NAME in files or PROGRESS_NAME in files:
            runs.append(path)
        elif (path / ".hydra").is_dir():
            hydra_jobs.append(path)
    never_started = [job for job in hydra_jobs if not any(run.is_relative_to(job) for run in runs)]
    return sorted(runs + never_started)


def _as_float(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(float(value)) else None


def _parse_float(text: Any) -> float | None:
    """A finite float from a config value's text, else ``None``."""
    try:
        return _as_float(float(text))
    except (TypeError, ValueError):
        return None


def _read_metrics(path: Path) -> tuple[dict[str, Any] | None, str | None]:
    file = path / METRICS_NAME
    if not file.is_file():
        return None, "no metrics.json"
    try:
        metrics = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        return None, f"unreadable metrics.json ({exc})"
    if not isinstance(metrics, dict):
        return None, "unreadable metrics.json (not an object)"
    return metrics, None


def _read_config_names(path: Path) -> dict[str, Any]:
    """``label``/``algo_name``/``env_name``/``seed``/``cost_limit`` from ``config.yaml``
    (top-level keys), ``env_id`` (the env block's ``id``), and ``algo_cost_limit``: whether
    the ``algo`` block has a ``cost_limit`` key at any depth (the constrained algorithms'
    resolved limit)."""
    file = path / CONFIG_NAME
    names: dict[str, Any] = {}
    if not file.is_file():
        return names
    in_algo = in_env = False
    names["algo_cost_limit"] = False
    for line in file.read_text(errors="replace").splitlines():
        if in_algo and line.startswith((" ", "\t")):
            names["algo_cost_limit"] |= line.strip().startswith("cost_limit:")
            continue
        if in_env and line.startswith("  id:"):
            names["env_id"] = line.partition(":")[2].strip().strip("'\"")
            continue
        if line.startswith((" ", "\t", "#")) or ":" not in line:
            continue
        key, _, value = line.partition(":")
        in_algo, in_env = key == "algo", key == "env"
        if key in {"label", "algo_name", "env_name", "seed", "cost_limit"} and value.strip():
            names[key] = value.strip().strip("'\"")
    return names


def read_progress(path: Path) -> tuple[dict[str, FloatArray], str | None]:
    """Columns of ``progress.csv`` as float arrays (NaN for empty cells) and a problem, if any."""
    file = path / PROGRESS_NAME
    if not file.is_file():
        return {}, "no progress.csv"
    try:
        with file.open(newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        return {}, f"unreadable progress.csv ({exc})"
    if len(rows) < 2:
        return {}, "empty progress.csv"
    header, body = rows[0], [row for row in rows[1:] if row]
    columns: dict[str, FloatArray] = {}
    for index, name in enumerate(header):
        values = []
        for row in body:
            cell = row[index] if index < len(row) else ""
            try:
                values.append(float(cell) if cell != "" else math.nan)
            except ValueError:
                values.append(math.nan)
        columns[name] = np.asarray(values, dtype=np.float64)
    if "env_steps" not in columns:
        return columns, "progress.csv has no env_steps column"
    return columns, None


def _tradeoff(metrics: dict[str, Any]) -> tuple[TradeoffPoint, ...]:
    points = []
    for entry in metrics.get("tradeoff") or []:
        if not isinstance(entry, dict):
            continue
        values = [_as_float(entry.get(k)) for k in ("clearance", "return_mean", "cost_mean")]
        if all(v is not None for v in values):
            points.append(TradeoffPoint(*values))  # type: ignore[arg-type]
    return tuple(points)


def steps_per_decision(path: Path, metrics: dict[str, Any] | None) -> int:
    """Low-level env steps per logged step: k for a Safety-Embedded MDP run, else 1."""
    semdp = (metrics or {}).get("semdp")
    if isinstance(semdp, dict) and isinstance(semdp.get("k"), int) and semdp["k"] >= 1:
        return int(semdp["k"])
    file = path / CONFIG_NAME
    if not file.is_file():
        return 1
    try:
        config = yaml.safe_load(file.read_text(errors="replace"))
        wrapper = config["env"]["wrapper"]
        if "SafetyEmbeddedEnv" in str(wrapper.get("_target_", "")):
            return max(int(wrapper.get("k", 1)), 1)
    except Exception:  # a malformed config only loses the scaling, never the run
        return 1
    return 1


def pretrain_steps(path: Path) -> int:
    """Env steps spent before the run's own (e.g. the SEMDP follower's training): the run's
    ``env.pretrain_steps``, 0 when absent. Fig. 3.3 starts the SEMDP curves after them."""
    file = path / CONFIG_NAME
    if not file.is_file():
        return 0
    try:
        config = yaml.safe_load(file.read_text(errors="replace"))
        return max(int(config["env"].get("pretrain_steps") or 0), 0)
    except Exception:  # a malformed config only loses the offset, never the run
        return 0


def _env(names: dict[str, Any], recorded: str) -> str:
    """The env's name for tables: the Safety Gym task the run stepped (from the config's env
    id: ``env=semdp_point_push1 env.task=Button1`` is PointButton1), else the recorded name."""
    return trained_env(str(names.get("env_id", "")), recorded)


def load_run(path: Path) -> RunRecord:
    """Read one run directory; never raises on missing or malformed files."""
    path = Path(path)
    metrics, metrics_problem = _read_metrics(path)
    curves, progress_problem = read_progress(path)
    if "env_steps" in curves:
        curves["env_steps"] = (curves["env_steps"] * steps_per_decision(path, metrics)
                               + pretrain_steps(path))
    problems = [p for p in (metrics_problem, progress_problem) if p]
    names = _read_config_names(path)
    cost_limit = _parse_float(names.get("cost_limit"))
    unconstrained = names.get("algo_cost_limit") is False
    if metrics is None:
        label = str(names.get("label") or algorithm_name(str(names.get("algo_name") or UNKNOWN)))
        env = _env(names, str(names.get("env_name") or UNKNOWN))
        seed_text = names.get("seed")
        seed = int(seed_text) if isinstance(seed_text, str) and seed_text.isdigit() else None
        status = "no metrics.json" if metrics_problem == "no metrics.json" else "unreadable"
        return RunRecord(
            path, status, None, label, env, seed, None, None, curves, (), tuple(problems),
            cost_limit, unconstrained,
        )
    status = str(metrics.get("status") or "unknown")
    evaluation = metrics.get("eval") if isinstance(metrics.get("eval"), dict) else {}
    eval_return = _as_float(evaluation.get("return_mean"))
    eval_cost = _as_float(evaluation.get("cost_mean"))
    if status == "completed" and (eval_return is None or eval_cost is None):
        problems.append("completed without a final evaluation")
    elif status != "completed":
        problems.insert(0, f"status {status}")
    seed = metrics.get("seed")
    return RunRecord(
        path=path,
        status=status,
        error=str(metrics["error"]) if metrics.get("error") else None,
        label=str(metrics.get("label") or algorithm_name(str(metrics.get("algo") or UNKNOWN))),
        env=_env(names, str(metrics.get("env") or UNKNOWN)),
        seed=int(seed) if isinstance(seed, int) and not isinstance(seed, bool) else None,
        eval_return=eval_return,
        eval_cost=eval_cost,
        curves=curves,
        tradeoff=_tradeoff(metrics),
        problems=tuple(problems),
        cost_limit=cost_limit,
        unconstrained=unconstrained,
    )


def load_runs(root: Path) -> list[RunRecord]:
    """:func:`load_run` on every directory :func:`find_run_dirs` finds below ``root``."""
    return [load_run(path) for path in find_run_dirs(root)]


def mean_and_standard_error(values: list[float] | FloatArray) -> tuple[float, float]:
    """Mean and standard error ``std(ddof=1) / sqrt(n)`` (NaN error for a single value).

    Raises:
        ValueError: on an empty input.
    """
    array = np.asarray(values, dtype=np.float64)
    if array.size == 0:
        raise ValueError("mean_and_standard_error needs at least one value")
    if array.size == 1:
        return float(array[0]), math.nan
    return float(array.mean()), float(array.std(ddof=1) / math.sqrt(array.size))
