"""The driving envs of thesis App. A.2 under the module path they had before the split into
:mod:`sims.driving.base` (the MDP both tasks share) and :mod:`sims.driving.tasks` (the circle
and the random path), so that ``from sims.driving.env import ...`` and checkpoints that pickled
an env as ``sims.driving.env.DriveCircleEnv`` keep resolving.
"""

from __future__ import annotations

from sims.driving.base import DrivingEnv
from sims.driving.tasks import DriveCircleEnv, DriveTrajectoryEnv

__all__ = ["DriveCircleEnv", "DriveTrajectoryEnv", "DrivingEnv"]
