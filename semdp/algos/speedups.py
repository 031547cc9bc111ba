"""The on-policy algorithms' opt-in speed-ups, built from their config keys and handed to the
algorithm (:func:`semdp.build.build_algorithm`); the algorithm files import none of them.

Three keys of ``conf/algo/_on_policy.yaml`` are read here, not by the algorithm:

* ``gradients``: ``written`` (the presets' choice) hands in the kernel of
  :mod:`semdp.algos.kernels.written`, the updates' derivatives written out for the default MLPs,
  checked at construction against the losses of the algorithm's own files; ``autograd`` hands in
  none (the algorithm's :class:`~semdp.algos.on_policy.Autograd`).
* ``vectorization`` (``sync`` | ``async`` | ``auto``) and ``parallel_critics`` (``false`` |
  ``true`` | ``auto``): the helper processes of :mod:`semdp.algos.helpers` that step part of
  the envs and regress the critics during the actor update; ``sync`` with ``false`` hands in
  none (both run in the trainer). No choice of these two changes a number.

The defaults of :func:`on_policy_seams` are the config's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.algos.helpers.critic_helper import CriticOwner
from semdp.algos.helpers.modes import with_helpers
from semdp.algos.kernels.written import WrittenDerivatives

#: The keys of an on-policy algorithm's config node that this module reads.
KEYS: tuple[str, ...] = ("gradients", "vectorization", "parallel_critics")
GRADIENTS: tuple[str, ...] = ("written", "autograd")
VECTORIZATION_MODES: tuple[str, ...] = ("sync", "async", "auto")


class HelperRunners:
    """The ``runners`` seam of :class:`~semdp.algos.on_policy.OnPolicyAlgorithm` with helper
    processes (:func:`semdp.algos.helpers.modes.with_helpers`). A plain class, not a
    dataclass: Hydra's ``instantiate`` would turn a dataclass argument into a config node."""

    def __init__(self, vectorization: str, parallel_critics: bool | str) -> None:
        self.vectorization, self.parallel_critics = vectorization, parallel_critics

    def __repr__(self) -> str:
        return f"HelperRunners({self.vectorization!r}, {self.parallel_critics!r})"

    def __call__(self, envs: gym.vector.VectorEnv,
                 policy: tuple[Any, Any, Callable[[Any], np.ndarray]], owner: CriticOwner,
                 regress: Callable[..., tuple[float, float] | None], local_critics: Any
                 ) -> tuple[Any, Any]:
        return with_helpers(self.vectorization, self.parallel_critics, envs, policy, owner,
                            regress, local_critics)


def on_policy_seams(gradients: str = "written", vectorization: str = "auto",
                    parallel_critics: bool | str = "auto") -> dict[str, Any]:
    """The ``kernel`` and ``runners`` arguments of an on-policy algorithm for these settings
    (None where the plain path runs)."""
    if gradients not in GRADIENTS:
        raise ValueError(f"algo.gradients must be one of {list(GRADIENTS)}, got {gradients!r}")
    if vectorization not in VECTORIZATION_MODES:
        raise ValueError(f"algo.vectorization must be one of {list(VECTORIZATION_MODES)}, "
                         f"got {vectorization!r}")
    if parallel_critics not in (True, False, "auto"):
        raise ValueError(f"algo.parallel_critics must be true, false or 'auto', "
                         f"got {parallel_critics!r}")
    plain = vectorization == "sync" and parallel_critics is False
    return {"kernel": WrittenDerivatives() if gradients == "written" else None,
            "runners": None if plain else HelperRunners(vectorization, parallel_critics)}
