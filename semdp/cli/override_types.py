"""A command-line value of the wrong type is bad input, found before anything is built.

Hydra accepts ``algo.gamma=abc`` for a key whose configured value is a number: the string would
reach the algorithm's constructor, or the first epoch. :func:`wrong_types` compares each value
override with the value the same key has in the config composed from the same config-group
choices without the value overrides, and names the first whose type does not fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from hydra import compose
from hydra.core.global_hydra import GlobalHydra
from omegaconf import DictConfig, OmegaConf


def _kind(value: object) -> str | None:
    """What a configured value must stay: ``number``, ``integer``, ``flag``, ``list`` (None:
    anything: strings, nulls and mappings are not checked)."""
    if isinstance(value, bool):
        return "flag"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if OmegaConf.is_list(value) or isinstance(value, list):
        return "list"
    return None


def _fits(kind: str, value: object) -> bool:
    if kind == "flag":
        return isinstance(value, bool)
    if kind == "list":
        return OmegaConf.is_list(value) or isinstance(value, list)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    # An integer key takes a whole float (total_steps=1e6); NaN and infinity are checked later,
    # with the key named, by the config's validation.
    return kind == "number" or not math.isfinite(value) or float(value).is_integer()


def _is_group(key: str) -> bool:
    loader = GlobalHydra.instance().config_loader()
    return "@" in key or bool(loader.get_group_options(key.lstrip("~+")))


def wrong_types(cfg: DictConfig, config_name: str, overrides: Sequence[str]) -> str | None:
    """The first value override in ``overrides`` whose value does not fit the type the key has
    without it, as a one-line reason, else None. Call inside a running Hydra app."""
    values = [o for o in overrides if "=" in o and not o.startswith(("~", "+", "hydra."))
              and not _is_group(o.split("=", 1)[0])]
    if not values:
        return None
    groups = [o for o in overrides if o not in values and not o.startswith("hydra.")]
    try:
        reference = compose(config_name=config_name, overrides=groups)
    except Exception:  # outside a Hydra app: nothing to compare with
        return None
    for override in values:
        key = override.split("=", 1)[0]
        try:
            configured = OmegaConf.select(reference, key)
            given = OmegaConf.select(cfg, key)
        except Exception:  # an interpolation that needs the run: not checked
            continue
        kind = _kind(configured)
        if kind is not None and not _fits(kind, given):
            shown = OmegaConf.to_container(given) if OmegaConf.is_config(given) else given
            return f"{key} must be {'an' if kind == 'integer' else 'a'} {kind}, got {shown!r}"
    return None
