"""Safety Gym replica in pymunk (Point/Car/Mass x Goal/Button/Push, levels 0-2).

Importing this package registers ``sims/Safety{Point,Car,Mass}{Goal,Button,Push}{0,1,2}-v0``
with gymnasium (1000-step episodes via ``max_episode_steps``)::

    import gymnasium, sims
    env = gymnasium.make("sims/SafetyPointPush1-v0", render_mode="rgb_array")
"""

from __future__ import annotations

import gymnasium

from sims.safety_gym.config import EPISODE_STEPS, LEVELS, ROBOTS, TASKS, all_env_ids, env_id
from sims.safety_gym.env import SafetyGymEnv
from sims.safety_gym.perception import obstacles_from_lidar

__all__ = ["ENV_IDS", "SafetyGymEnv", "env_id", "make", "obstacles_from_lidar"]

ENV_IDS: list[str] = all_env_ids()


def make(robot: str, task: str, level: int, **kwargs) -> gymnasium.Env:
    """``gymnasium.make`` by parts; raises ``ValueError`` listing valid robots/tasks/levels."""
    return gymnasium.make(env_id(robot, task, level), **kwargs)


def _register() -> None:
    for robot in ROBOTS:
        for task in TASKS:
            for level in LEVELS:
                name = env_id(robot, task, level)
                if name in gymnasium.registry:
                    continue
                gymnasium.register(
                    id=name,
                    entry_point="sims.safety_gym.env:SafetyGymEnv",
                    max_episode_steps=EPISODE_STEPS,
                    kwargs={"robot": robot, "task": task, "level": level},
                )


_register()
