"""A run directory's saved ``config.yaml``, loaded so that it still instantiates today.

Runs keep the config they ran with (``semdp-train`` writes it; resume, ``semdp-eval`` and the
reference tables read it back). Classes and functions that moved since keep working: every
``_target_`` in :data:`RENAMED_TARGETS` is rewritten to the module path of today on load; nothing
else changes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from omegaconf import DictConfig, ListConfig, OmegaConf

#: ``_target_`` written by earlier versions -> the same class today.
RENAMED_TARGETS: dict[str, str] = {
    "semdp.common.lagrange.Lagrange": "semdp.algos.lagrangian.Lagrange",
    "semdp.common.lagrange.PIDLagrange": "semdp.algos.pid_lagrange.PIDLagrange",
    "semdp.common.self_paced.SelfPacedThresholds": "semdp.algos.sp_ppo_lag.SelfPacedThresholds",
    "semdp.embedded.artifacts.after_training": "semdp.reporting.semdp_run.after_training",
}


def rename_targets(node: Any) -> int:
    """Rewrite the moved ``_target_`` paths of ``node`` in place; return how many."""
    count = 0
    if isinstance(node, DictConfig):
        target = node.get("_target_") if "_target_" in node else None
        if isinstance(target, str) and target in RENAMED_TARGETS:
            node._target_ = RENAMED_TARGETS[target]
            count += 1
        for key in node:
            if not (OmegaConf.is_missing(node, key) or OmegaConf.is_interpolation(node, key)):
                count += rename_targets(node[key])
    elif isinstance(node, ListConfig):
        for item in node:
            count += rename_targets(item)
    return count


def load_run_config(path: str | Path) -> DictConfig:
    """``OmegaConf.load`` of a run's ``config.yaml`` (or of the run directory holding it) with
    the moved ``_target_`` paths renamed.

    Raises:
        ValueError: no such file, or one that is not a YAML mapping (one line naming it).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "config.yaml"
    if not path.is_file():
        raise ValueError(f"{path}: no such run config")
    try:
        cfg = OmegaConf.load(path)
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" (line {where.line + 1})" if where is not None else ""
        raise ValueError(f"{path}: not a YAML config{line}: "
                         f"{getattr(exc, 'problem', None) or type(exc).__name__}") from None
    if not isinstance(cfg, DictConfig):
        raise ValueError(f"{path} is not a mapping")
    rename_targets(cfg)
    return cfg
