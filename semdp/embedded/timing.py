"""The Safety-Embedded MDP's time split (thesis §3.6): where the SEMDP envs of a run spent their
time (perception, planning, following, simulation), summed over a run's envs and per epoch.

:func:`timing_summary` sums the counters of :class:`~semdp.embedded.wrapper.SafetyEmbeddedEnv`
over every sub-env of some vector envs (``metrics.json["semdp"]``,
:func:`semdp.reporting.semdp_run.throughput`); :class:`EpochTimeSplit` is the per-epoch form, a
:class:`semdp.common.logger.RowSource` that adds the ``time_*`` columns to ``progress.csv``
(training and periodic-evaluation envs together, and the rest of the epoch's wall time:
learning and overhead).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from semdp.common.logger import TIME_SPLIT_COLUMNS
from semdp.embedded.wrapper import TIMING_KEYS, SafetyEmbeddedEnv


def find_semdp(env: gym.Env) -> SafetyEmbeddedEnv | None:
    """The :class:`SafetyEmbeddedEnv` inside a wrapper chain, or ``None``."""
    while env is not None:
        if isinstance(env, SafetyEmbeddedEnv):
            return env
        env = getattr(env, "env", None)
    return None


def timing_summary(
    vec_envs: list[gym.vector.VectorEnv | None], elsewhere: bool = False
) -> dict[str, float]:
    """Summed wrapper timings and step counts over every sub-env of the given vector envs;
    with ``elsewhere``, also what their copies did in evaluation helper processes (work done,
    not this process's wall time)."""
    totals = dict.fromkeys(TIMING_KEYS, 0.0)
    totals.update(high_level_steps=0, low_level_steps=0)
    for vec in vec_envs:
        for sub in getattr(vec, "envs", []) if vec is not None else []:
            semdp = find_semdp(sub)
            if semdp is None:
                continue
            for key in TIMING_KEYS:
                totals[key] += semdp.timing[key]
            totals["high_level_steps"] += semdp.high_level_steps
            totals["low_level_steps"] += semdp.low_level_steps
            if elsewhere:
                for key, value in semdp.elsewhere.items():
                    totals[key] = totals.get(key, 0.0) + value
    return totals


def has_semdp_env(algo: Any) -> bool:
    """Whether ``algo``'s training vector env holds a :class:`SafetyEmbeddedEnv`."""
    return any(find_semdp(sub) is not None for sub in getattr(algo.envs, "envs", []))


class EpochTimeSplit:
    """Per-epoch deltas of the wrapper timings of ``algo``'s envs (read when each row is written,
    so a resumed run's restored env is the one measured)."""

    columns: tuple[str, ...] = TIME_SPLIT_COLUMNS

    def __init__(self, algo: Any) -> None:
        self.algo = algo
        self._inside: dict[str, float] = dict.fromkeys(TIMING_KEYS, 0.0)
        self._wall = 0.0

    def _totals(self) -> dict[str, float]:
        totals = timing_summary([self.algo.envs, self.algo.eval_envs])
        return {key: float(totals[key]) for key in TIMING_KEYS}

    def start(self) -> None:
        """Take the current sums as the baseline of the first epoch."""
        self._inside = self._totals()
        self._wall = float(self.algo.wall_time)

    def values(self, row: Mapping[str, Any]) -> dict[str, float]:
        """Seconds of this epoch: ``time_<part>_s`` and ``time_learning_and_overhead_s``."""
        inside, wall = self._totals(), float(self.algo.wall_time)
        delta = {key: inside[key] - self._inside[key] for key in TIMING_KEYS}
        out = {f"time_{key}": value for key, value in delta.items()}
        out["time_learning_and_overhead_s"] = max(wall - self._wall - sum(delta.values()), 0.0)
        self._inside, self._wall = inside, wall
        return out
