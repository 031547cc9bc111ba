"""Names as a reader of the thesis expects them in tables and legends.

Runs without a ``label`` are named by their Hydra choices (``ppo_lag``, ``point_goal1``,
``drive_circle_v4.0``); the report shows ``PPO-Lag``, ``PointGoal1``, ``Circle 4 m/s``.
Labels set by the presets (``Ours``, ``PPO Lag`` as in Table 3.1) are kept as they are.
"""

from __future__ import annotations

import re

ALGORITHMS: dict[str, str] = {
    "ppo": "PPO", "ppo_lag": "PPO-Lag", "sp_ppo_lag": "SP-PPO-Lag", "trpo": "TRPO",
    "trpo_lag": "TRPO-Lag", "cpo": "CPO", "sac": "SAC",
}
_SAFETY_GYM = re.compile(r"^(?:semdp_)?(point|car|mass)_(goal|button|push)(\d)$")
_SAFETY_GYM_ID = re.compile(r"Safety(Point|Car|Mass)(Goal|Button|Push)(\d)-v\d+$")
_DRIVING = re.compile(r"^drive_(circle|trajectory)(?:_v(\d+(?:\.\d+)?))?$")


def algorithm_name(name: str) -> str:
    """``ppo_lag`` -> ``PPO-Lag``; any other name unchanged."""
    return ALGORITHMS.get(name, name)


def env_name(name: str) -> str:
    """``point_goal1`` (and the SEMDP env ``semdp_point_goal1``) -> ``PointGoal1``,
    ``drive_circle_v4.0`` -> ``Circle 4 m/s``; any other
    name unchanged."""
    match = _SAFETY_GYM.match(name)
    if match:
        robot, task, level = match.groups()
        return f"{robot.capitalize()}{task.capitalize()}{level}"
    match = _DRIVING.match(name)
    if match:
        track, speed = match.groups()
        return track.capitalize() + (f" {float(speed):g} m/s" if speed else "")
    return name


def env_name_from_id(env_id: str) -> str | None:
    """``sims/SafetyPointButton1-v0`` -> ``PointButton1``: the task a run stepped, whatever
    option composed it (``env=semdp_point_push1 env.task=Button1`` steps PointButton1); None
    for any other id."""
    match = _SAFETY_GYM_ID.search(env_id)
    return "".join(match.groups()) if match else None



def trained_env(env_id: str, recorded: str) -> str:
    """The env's name for tables: the Safety Gym task a run stepped, from its config's gymnasium
    id (``env=semdp_point_push1 env.task=Button1`` is PointButton1), else :func:`env_name` of
    the recorded name."""
    return env_name_from_id(env_id) or env_name(recorded)
