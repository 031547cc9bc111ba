"""Argument checks of the toy problem's solver (thesis §2.5.1): each raises ValueError naming
the parameter, so that a bad value in ``conf/toy.yaml`` is reported by its key."""

from __future__ import annotations

import math
import numbers


def check_real(name: str, value: object) -> float:
    """Return ``value`` as a finite float or raise ValueError naming the parameter."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    result = float(value)
    if not math.isfinite(result):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return result


def check_int(name: str, value: object, minimum: int) -> int:
    """Return ``value`` as an int ``>= minimum`` (bools rejected) or raise ValueError."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def check_positive(name: str, value: object) -> float:
    """Return ``value`` as a finite float ``> 0`` or raise ValueError."""
    result = check_real(name, value)
    if result <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return result


def check_choice(name: str, value: object, options: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``options``, else raise ValueError listing them."""
    if value not in options:
        raise ValueError(f"{name} must be one of {list(options)}, got {value!r}")
    return str(value)
