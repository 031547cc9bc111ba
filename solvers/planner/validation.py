"""Checks shared by the planner's settings dataclasses (problem and backends).

Each returns the normalised value (``float``, ``int``, ``bool``, ``dict``) or raises
``ValueError`` naming the setting and the value it got, so every frozen settings object is
valid once built and nothing downstream checks again.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping

import numpy as np


def number(name: str, value: object, bound: str, ok: Callable[[float], bool]) -> float:
    """``value`` as a finite float for which ``ok`` holds (``bound`` describes it: ``"> 0"``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
    result = float(value)
    if not math.isfinite(result) or not ok(result):
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
    return result


def positive(name: str, value: object) -> float:
    """A finite number > 0."""
    return number(name, value, "> 0", lambda v: v > 0)


def non_negative(name: str, value: object) -> float:
    """A finite number >= 0."""
    return number(name, value, ">= 0", lambda v: v >= 0)


def count(name: str, value: object, least: int) -> int:
    """An integer (or an integral float) >= ``least``."""
    integral = isinstance(value, numbers.Integral) or (
        isinstance(value, numbers.Real)
        and math.isfinite(float(value))
        and float(value).is_integer()
    )
    if isinstance(value, bool) or not integral or int(value) < least:  # type: ignore[call-overload]
        raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)  # type: ignore[call-overload]


def flag(name: str, value: object) -> bool:
    """A boolean (numpy's and the integers 0 and 1 included)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral) and int(value) in (0, 1):
        return bool(value)
    raise ValueError(f"{name} must be a boolean, got {value!r}")


def mapping(name: str, value: object) -> dict[str, object]:
    """A mapping (None: empty) as a plain dict with string keys."""
    if value is not None and not isinstance(value, Mapping):
        raise ValueError(f"{name} must be a mapping or None, got {value!r}")
    return {str(k): v for k, v in (value or {}).items()}


def set_field(obj: object, name: str, value: object) -> None:
    """Store a normalised value on a frozen dataclass (in ``__post_init__``)."""
    object.__setattr__(obj, name, value)
