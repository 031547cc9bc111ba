"""Checks of what the driving envs are given (thesis App. A.2): constructor arguments and the
``[steer, throttle]`` action, clipped to [-1, 1]."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def check_range(name: str, value: float, low: float, high: float, valid: str) -> None:
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number in {valid}, got {value!r}") from exc
    if not (math.isfinite(number) and low < number <= high):
        raise ValueError(f"{name} must be in {valid}, got {value!r}")


def parse_action(action: Any) -> tuple[float, float]:
    """``(steer, throttle)`` clipped to [-1, 1]; raises ValueError on NaN or a wrong shape."""
    if isinstance(action, np.ndarray):
        if action.shape != (2,):
            raise ValueError(f"action must have shape (2,) = [steer, throttle], "
                             f"got shape {action.shape}")
        steer, throttle = action.tolist()
    else:
        try:
            steer, throttle = (float(v) for v in action)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"action must be two numbers [steer, throttle], "
                             f"got {action!r}") from exc
    if steer != steer or throttle != throttle:
        raise ValueError(f"action contains NaN: {action!r}; expected [steer, throttle] in "
                         f"[-1, 1]")
    steer = 1.0 if steer > 1.0 else (-1.0 if steer < -1.0 else steer)
    throttle = 1.0 if throttle > 1.0 else (-1.0 if throttle < -1.0 else throttle)
    return float(steer), float(throttle)
