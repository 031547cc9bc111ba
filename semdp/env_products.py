"""The env options that are products of a robot and a task, registered in Hydra's ConfigStore.

Two families of ``env=`` options are the same node for every robot x task pair:

- ``env=<robot>_<task><level>`` (18: Point, Car, Mass x Goal, Button, Push x levels 1, 2): the
  pymunk Safety Gym replica ``sims/Safety<Robot><Task><Level>-v0`` on ``conf/env/_base.yaml``;
- ``env=semdp_<robot>_<task><level>`` (12: the three robots x Goal1, Goal2, Push1, Push2): the
  Safety-Embedded MDP ``conf/env/_semdp.yaml`` with ``robot=<robot>`` (``conf/robot/<robot>.yaml``)
  and ``task: <Task><Level>``.

:func:`register` stores one node per pair in the ``env`` group, with the defaults list and keys a
YAML file of that name would hold, so ``env=point_goal1``, ``env=semdp_car_push1`` and sweeps
such as ``env=point_goal1,point_goal2`` compose as Hydra options like the files of ``conf/env/``.
Importing :mod:`semdp.paths` (every Hydra app, :mod:`semdp.configs`) registers them; every other
option of ``conf/`` is a YAML file.
"""

from __future__ import annotations

from typing import Any

from hydra.core.config_store import ConfigStore

ROBOTS = ("point", "car", "mass")
#: The Safety Gym replica's tasks with obstacles (level 0, obstacle-free, is the followers' task).
SAFETY_GYM_TASKS = ("goal1", "goal2", "button1", "button2", "push1", "push2")
#: The tasks of the Safety-Embedded MDP experiments (thesis §3.6: Push1, Goal1; and level 2).
SEMDP_TASKS = ("goal1", "goal2", "push1", "push2")


def safety_gym_node(robot: str, task: str) -> dict[str, Any]:
    """``env=<robot>_<task>``: e.g. ``car_button2`` -> ``sims/SafetyCarButton2-v0``."""
    return {"defaults": ["_base", "_self_"], "id": f"sims/Safety{robot.title()}{task.title()}-v0"}


def semdp_node(robot: str, task: str) -> dict[str, Any]:
    """``env=semdp_<robot>_<task>``: the SEMDP env node with the robot's settings and the task
    (``_semdp.yaml`` builds the id ``sims/Safety<Robot><Task>-v0`` from both)."""
    return {"defaults": ["_semdp", {"override /robot@_global_.robot": robot}, "_self_"],
            "task": task.title()}


def product_names() -> list[str]:
    """The 30 registered option names of the ``env`` group."""
    return [*(f"{robot}_{task}" for robot in ROBOTS for task in SAFETY_GYM_TASKS),
            *(f"semdp_{robot}_{task}" for robot in ROBOTS for task in SEMDP_TASKS)]


def register() -> None:
    """Store the product nodes in Hydra's ConfigStore (idempotent)."""
    store = ConfigStore.instance()
    for robot in ROBOTS:
        for task in SAFETY_GYM_TASKS:
            store.store(name=f"{robot}_{task}", group="env", node=safety_gym_node(robot, task),
                        provider="semdp")
        for task in SEMDP_TASKS:
            store.store(name=f"semdp_{robot}_{task}", group="env", node=semdp_node(robot, task),
                        provider="semdp")
