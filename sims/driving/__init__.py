"""Driving tasks: dynamic bicycle model with brush tyres (Circle, Trajectory), thesis App. A.2.

Importing this package registers ``sims/DriveCircle-v0`` and ``sims/DriveTrajectory-v0``.
Episode length is a constructor argument (``episode_length``, default 200 steps of 0.05 s =
10 s); the env truncates by itself, so no TimeLimit wrapper is registered. Pass
``gym.make(id, episode_length=N)``: gymnasium's own ``max_episode_steps`` argument would only add
an outer TimeLimit and leave the env's horizon (used for the termination charge) unchanged.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from sims.driving.base import DrivingEnv
from sims.driving.controller import PurePursuitController, run_episode
from sims.driving.tasks import DriveCircleEnv, DriveTrajectoryEnv
from sims.driving.tracks import CircleTrack, RandomPathTrack
from sims.driving.vehicle import BicycleModel, VehicleParams, fiala_lateral_force

__all__ = [
    "BicycleModel",
    "CircleTrack",
    "DriveCircleEnv",
    "DriveTrajectoryEnv",
    "DrivingEnv",
    "PurePursuitController",
    "RandomPathTrack",
    "VehicleParams",
    "fiala_lateral_force",
    "run_episode",
]

for _env_id, _entry_point in (
    ("sims/DriveCircle-v0", "sims.driving.tasks:DriveCircleEnv"),
    ("sims/DriveTrajectory-v0", "sims.driving.tasks:DriveTrajectoryEnv"),
):
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point, disable_env_checker=False)
