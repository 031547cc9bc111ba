"""A run directory's saved ``config.yaml``, loaded so that it still instantiates today.

Runs keep the config they ran with (``semdp-train`` writes it; resume, ``semdp-eval`` and the
reference tables read it back). A config of an earlier version is brought to today's form on load
by :func:`semdp.legacy.upgrade_run_config` (moved ``_target_`` paths, planner nodes of earlier
forms, ...); a config of today's form is left as it is.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from omegaconf import DictConfig, OmegaConf

from semdp.legacy import upgrade_run_config


def load_run_config(path: str | Path) -> DictConfig:
    """``OmegaConf.load`` of a run's ``config.yaml`` (or of the run directory holding it) in
    today's form (:func:`semdp.legacy.upgrade_run_config`).

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
    try:
        return upgrade_run_config(cfg)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
