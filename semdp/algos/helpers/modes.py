"""Which helper processes an on-policy algorithm uses (``vectorization``, ``parallel_critics``).

``"sync"``/``False`` keep the plain path; ``"async"``/``True`` always use the helper;
``"auto"`` (the default of both) uses a helper where the platform can fork and two CPUs are
available, and only while it is faster: :class:`~semdp.algos.helpers.option_probe.FasterOption`
measures both ways and keeps the faster (where a core is idle at the start, it begins with the
helpers). Sub-envs with a wrapper of their own stay in the trainer (its state, e.g. the SEMDP
wrapper's timings, is read from the trainer's copy), and so do envs whose step is cheaper than
the pipe (:data:`~semdp.algos.helpers.rollout_helper.ASYNC_MIN_STEP_S`). No choice changes a number.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.algos.helpers.critic_helper import CriticOwner, HelperCritics
from semdp.algos.helpers.option_probe import FasterOption, idle_core
from semdp.algos.helpers.rollout_helper import HelperCollector
from semdp.algos.rollout import LocalCollector
from semdp.common.networks import GaussianActor
from semdp.common.normalization import RunningNormalizer
from solvers.workers import fork_available

#: Modules whose wrappers keep no state the trainer reads (``auto`` may fork the envs).
_PLAIN_WRAPPER_MODULES: tuple[str, ...] = ("gymnasium.", "semdp.envs")


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - platforms without sched_getaffinity
        return os.cpu_count() or 1


def _plain_sub_envs(envs: gym.vector.VectorEnv) -> bool:
    """A plain ``SyncVectorEnv`` (not a subclass with a ``step`` of its own) whose sub-envs'
    wrappers are all gymnasium's or the cost checks of :mod:`semdp.envs`."""
    if type(envs) is not gym.vector.SyncVectorEnv:
        return False
    for env in envs.envs:
        while isinstance(env, gym.Wrapper):
            if not type(env).__module__.startswith(_PLAIN_WRAPPER_MODULES):
                return False
            env = env.env
    return True


def check_modes(vectorization: str, parallel_critics: bool | str, envs: gym.vector.VectorEnv
                ) -> None:
    """Raise ``ValueError`` for modes the platform or the envs cannot run."""
    if "async" in (vectorization, parallel_critics) or parallel_critics is True:
        if not fork_available():
            raise ValueError("helper processes need the 'fork' start method")
    if vectorization == "async" and type(envs) is not gym.vector.SyncVectorEnv:
        raise ValueError(f"vectorization='async' steps the sub-envs of a gymnasium "
                         f"SyncVectorEnv, got {type(envs).__name__}")


def with_helpers(
    vectorization: str,
    parallel_critics: bool | str,
    envs: gym.vector.VectorEnv,
    policy: tuple[GaussianActor, RunningNormalizer, Callable[[Any], np.ndarray]],
    owner: CriticOwner,
    regress: Callable[..., tuple[float, float] | None],
    local_critics: Any,
) -> tuple[Any, Any]:
    """The rollout collector and the critic runner for these modes.

    Args:
        vectorization, parallel_critics: the algorithm's settings (see the module docstring).
        envs: the training envs.
        policy: actor, normaliser and action scaling of the algorithm.
        owner: the algorithm (its critics).
        regress: the critic regression with its kernel bound.
        local_critics: the plain critic runner, used where the critics stay in the trainer.
    """
    check_modes(vectorization, parallel_critics, envs)
    helpers = fork_available() and _cpus() >= 2
    # with a core idle now, the helpers are used from the first epoch (option_probe)
    first = helpers and "auto" in (vectorization, parallel_critics) and idle_core()
    if vectorization == "sync":
        collector: Any = LocalCollector(*policy)
    else:
        env_choice = FasterOption(helpers and _plain_sub_envs(envs), first=first)
        collector = HelperCollector(*policy, vectorization, env_choice)
    if parallel_critics is False:
        return collector, local_critics
    return collector, HelperCritics(owner, regress, parallel_critics,
                                    FasterOption(helpers, first=first))
