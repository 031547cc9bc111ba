"""Compose configs of ``conf/`` from Python, as the Hydra apps do (no YAML is read by hand).

    cfg = compose_config("train", ["experiment=semdp", "robot=car"])
    planner = instantiate(compose_node("planner", "ipopt", ["clearance=0.6"]))

The options are Hydra's: the YAML files of ``conf/`` and the robot x task ``env`` options that
importing :mod:`semdp.paths` registers in the ConfigStore (:mod:`semdp.env_products`).
"""

from __future__ import annotations

from collections.abc import Sequence

from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, open_dict

from semdp.paths import CONF_DIR


def compose_config(config_name: str, overrides: Sequence[str] = ()) -> DictConfig:
    """The primary config ``conf/<config_name>.yaml`` composed with Hydra ``overrides``.

    As in a Hydra app, ``${hydra:runtime.choices.<group>}`` resolves (the presets use it): the
    Hydra node is registered with :class:`HydraConfig` and removed from the returned config.
    Outside a running app only: inside one, the app's own Hydra state would be replaced.
    """
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name=config_name, overrides=list(overrides),
                      return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)
    with open_dict(cfg):
        del cfg["hydra"]
    return cfg


def group_options(group: str) -> list[str]:
    """The options of a config group as Hydra lists them (files and ConfigStore nodes), without
    the ``_``-prefixed bases (``env/_base``, ``method/_semdp``)."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        options = GlobalHydra.instance().config_loader().get_group_options(group)
    return sorted(name for name in options if not name.startswith("_"))


def compose_node(group: str, name: str, overrides: Sequence[str] = ()) -> DictConfig:
    """One option of a config group (e.g. ``compose_node("planner", "ipopt")``), with
    ``overrides`` of its keys (``["clearance=0.6"]``).

    Raises:
        ValueError: ``name`` is not an option of ``group`` (the message lists the options).
    """
    options = group_options(group)
    if name not in options:
        raise ValueError(f"unknown {group} {name!r}; options: {options}")
    cfg = compose_config(f"{group}/{name}", [f"{group}.{item}" for item in overrides])
    node = cfg[group]
    assert isinstance(node, DictConfig)
    return node
