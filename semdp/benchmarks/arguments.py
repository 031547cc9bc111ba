"""``key=value`` arguments of the ``semdp-bench`` suites: one syntax and one parser for all.

Every suite declares its keys with their defaults (strings) and calls :func:`parse_args`::

    args = parse_args("driving", argv, {"steps": "20000", "speeds": "[1,2,3]"})
    steps, speeds = as_int(args, "steps", minimum=1), as_list(args["speeds"])

Values stay strings until the suite converts them with :func:`as_int`, :func:`as_float`,
:func:`as_bool` or :func:`as_list` (``[a,b]`` or ``a,b``). The GNU spelling of older commands
is translated first: ``--num-envs 8`` is ``num_envs=8``, ``--robots point car`` is
``robots=[point,car]``, ``--calibration`` is ``calibration=true`` and ``--no-async`` is
``async=false``. A bad argument raises :class:`BenchArgumentError`, a ``SystemExit`` whose
message names the suite and lists the valid keys.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

TRUE = ("1", "true", "yes", "on")
FALSE = ("0", "false", "no", "off")


class BenchArgumentError(SystemExit):
    """A bad ``semdp-bench`` argument; the message names the suite and the valid keys."""


def _from_gnu(argv: Sequence[str]) -> list[str]:
    """``--key value...`` / ``--flag`` / ``--no-flag`` / ``--key=value`` as ``key=value`` items."""
    items: list[str] = []
    i = 0
    while i < len(argv):
        item = argv[i]
        i += 1
        if not item.startswith("--"):
            items.append(item)
            continue
        name, sep, value = item[2:].partition("=")
        key = name.replace("-", "_")
        if sep:
            items.append(f"{key}={value}")
            continue
        values = []
        while i < len(argv) and not argv[i].startswith("--") and "=" not in argv[i]:
            values.append(argv[i])
            i += 1
        if len(values) > 1:
            items.append(f"{key}=[{','.join(values)}]")
        elif values:
            items.append(f"{key}={values[0]}")
        elif key.startswith("no_"):
            items.append(f"{key[3:]}=false")
        else:
            items.append(f"{key}=true")
    return items


def parse_args(suite: str, argv: Sequence[str], defaults: Mapping[str, str]) -> dict[str, str]:
    """``key=value`` items over ``defaults`` (a later item wins).

    Raises:
        BenchArgumentError: for an item without ``=`` or with a key not in ``defaults``.
    """
    args = dict(defaults)
    for item in _from_gnu(argv):
        key, sep, value = item.partition("=")
        if not sep or key not in defaults:
            raise BenchArgumentError(
                f"semdp-bench {suite}: unknown argument {item!r}; valid: "
                + " ".join(f"{k}={v}" for k, v in defaults.items())
            )
        args[key] = value
    return args


def _bad(key: str, value: str, what: str) -> BenchArgumentError:
    return BenchArgumentError(f"semdp-bench: {key} must be {what}, got {value!r}")


def as_int(args: Mapping[str, str], key: str, minimum: int | None = None) -> int:
    """``args[key]`` as an integer (at least ``minimum``)."""
    try:
        value = int(args[key])
    except ValueError:
        raise _bad(key, args[key], "an integer") from None
    if minimum is not None and value < minimum:
        raise _bad(key, args[key], f"an integer >= {minimum}")
    return value


def as_float(args: Mapping[str, str], key: str) -> float:
    """``args[key]`` as a finite float."""
    try:
        value = float(args[key])
    except ValueError:
        raise _bad(key, args[key], "a number") from None
    if not math.isfinite(value):
        raise _bad(key, args[key], "a finite number")
    return value


def as_bool(args: Mapping[str, str], key: str) -> bool:
    """``args[key]`` as a boolean (``true/false``, ``yes/no``, ``on/off``, ``1/0``)."""
    value = args[key].strip().lower()
    if value in TRUE:
        return True
    if value in FALSE:
        return False
    raise _bad(key, args[key], f"one of {TRUE + FALSE}")


def as_list(value: str) -> list[str]:
    """``[a,b]`` or ``a,b`` as ``["a", "b"]`` (empty entries dropped)."""
    return [item.strip() for item in value.strip().strip("[]").split(",") if item.strip()]


def as_items(args: Mapping[str, str], key: str) -> list[str]:
    """``args[key]`` as a non-empty list (``[a,b]`` or ``a,b``)."""
    items = as_list(args[key])
    if not items:
        raise _bad(key, args[key], "a non-empty list like [a,b]")
    return items


def as_choices(args: Mapping[str, str], key: str, valid: Sequence[object]) -> list[str]:
    """``args[key]`` as a non-empty list whose entries are all in ``valid``."""
    items = as_list(args[key])
    names = [str(v) for v in valid]
    if not items or any(item not in names for item in items):
        raise _bad(key, args[key], f"a list of {names}")
    return items
