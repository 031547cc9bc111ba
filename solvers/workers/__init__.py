"""Helper processes for every part of the project (:mod:`solvers.workers.helper`).

A torch-free toolkit, so that the planner's batch helpers use it as the training helpers do.
"""

from solvers.workers.helper import Helper, HelperError, describe_exit, fork_available

__all__ = ["Helper", "HelperError", "describe_exit", "fork_available"]
