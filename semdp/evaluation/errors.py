"""The error ``semdp-eval`` reports as one line (docs/evaluation.md)."""

from __future__ import annotations


class EvalError(ValueError):
    """A bad ``semdp-eval`` argument or run directory; the message names the problem."""
