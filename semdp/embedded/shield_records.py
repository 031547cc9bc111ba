"""What the low-level safety filter (:mod:`semdp.embedded.shield`) counts and records: its
per-episode counters and, for a recorder hook, one typed record per filter call (the cost
trace of :mod:`semdp.evaluation.cost_trace` reads them)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from semdp.embedded.robot_models import RobotModel, RobotState

#: The ways ``SafetyShield.filter`` can go: no cost region within reach (``"unchecked"``),
#: the action certified (``"kept"``), braking (``"braked"``), the best escape (``"escaped"``).
FILTER_BRANCHES = ("unchecked", "kept", "braked", "escaped")


@dataclass
class ShieldStats:
    """The filter's counts since it was made (:attr:`semdp.embedded.shield.SafetyShield.stats`)."""

    steps: int = 0
    checked: int = 0
    braked: int = 0
    escaped: int = 0


@dataclass(frozen=True)
class FilterRecord:
    """One ``SafetyShield.filter`` call, as a set ``SafetyShield.recorder`` receives it.

    Attributes:
        shield: the filter (its ``cost_regions`` and ``clearance`` re-evaluate the
            decision).
        model: the robot model the filter used.
        base: the unwrapped env, still before the step.
        obs: the observation the filter read.
        state: the robot state the filter read.
        proposed: the action given to the filter.
        applied: the action it returned.
        branch: one of :data:`FILTER_BRANCHES`.
    """

    shield: Any
    model: RobotModel
    base: Any
    obs: np.ndarray
    state: RobotState
    proposed: np.ndarray
    applied: np.ndarray
    branch: str


def branch_of(before: tuple[int, int, int], stats: ShieldStats) -> str:
    """The branch of one filter call from its counter increments (``before``: checked, braked,
    escaped at its start)."""
    if stats.escaped > before[2]:
        return "escaped"
    if stats.braked > before[1]:
        return "braked"
    return "kept" if stats.checked > before[0] else "unchecked"
