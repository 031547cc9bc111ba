"""sims: pymunk + gymnasium environments (Safety Gym replica, driving tasks).

A library: imports pymunk, gymnasium and numpy only -- never torch, Hydra or :mod:`solvers`.
Importing this package registers every environment id (``sims/...``) with gymnasium.
"""

from sims import driving as driving
from sims import safety_gym as safety_gym
