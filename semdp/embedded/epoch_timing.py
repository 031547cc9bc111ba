"""The Safety-Embedded MDP time split per epoch, as ``progress.csv`` columns.

A :class:`semdp.common.logger.RowSource`: each epoch's seconds spent inside the SEMDP envs
(perception, planning, following, simulation; training and periodic-evaluation envs together)
and the rest of the epoch's wall time (learning and overhead), the per-epoch form of
``metrics.json["semdp"]["time_split_s"]`` (:func:`semdp.embedded.artifacts.throughput`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from semdp.common.logger import TIME_SPLIT_COLUMNS
from semdp.embedded.artifacts import find_semdp, timing_summary
from semdp.embedded.wrapper import TIMING_KEYS


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
