"""sims: pymunk + gymnasium environments (Safety Gym replica, driving tasks).

A library: imports pymunk, gymnasium and numpy only -- never torch, Hydra or :mod:`solvers`.
Importing this package registers every environment id with gymnasium: ``sims/...`` and the test
CMDP ``semdp/SpeedLimit-v0`` (:mod:`sims.testbed`, registered first: it needs no pymunk).
"""

from sims import testbed as testbed  # isort: skip  (before the pymunk envs)
from sims import driving as driving
from sims import safety_gym as safety_gym
