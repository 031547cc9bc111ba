"""Differences between two methods in a report: ``A - B`` per environment and metric, with the
standard error of the difference and the difference in those standard errors (the form the
thesis' claims are judged in: docs/results.md, "The thesis' claims, one by one")."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from semdp.reporting.runs import mean_and_standard_error

METRICS: tuple[str, ...] = ("reward", "cost")


def difference(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """``mean(a) - mean(b)`` and its standard error ``sqrt(SE_a^2 + SE_b^2)`` (independent
    seeds); the error is NaN when either side has fewer than two values, both NaN if one is
    empty."""
    if not a or not b:
        return math.nan, math.nan
    (mean_a, se_a), (mean_b, se_b) = mean_and_standard_error(a), mean_and_standard_error(b)
    return mean_a - mean_b, math.hypot(se_a, se_b)


def difference_lines(
    values: Mapping[tuple[str, str, str], list[float]],
    envs: Sequence[str],
    first: str,
    second: str,
    digits: int = 2,
    title: str = "final evaluation",
) -> list[str]:
    """Markdown section: per environment ``first - second`` of each metric as
    ``difference ± SE`` and the difference in standard errors."""
    lines = [
        f"## {first} − {second} ({title})", "",
        "Difference of the means over seeds ± its standard error (sqrt(SE₁² + SE₂²)), and the "
        "difference in those standard errors.", "",
        "| env | " + " | ".join(f"{m}: difference | {m}: in SE" for m in METRICS) + " |",
        "|---|" + "---|---|" * len(METRICS),
    ]  # fmt: skip
    for env in envs:
        cells = []
        for metric in METRICS:
            diff, error = difference(values.get((env, first, metric), []),
                                     values.get((env, second, metric), []))
            if math.isnan(diff):
                cells += ["–", "–"]
            elif math.isnan(error) or error == 0:
                cells += [f"{diff:+.{digits}f} ± –", "–"]
            else:
                cells += [f"{diff:+.{digits}f} ± {error:.{digits}f}", f"{diff / error:+.1f}"]
        lines.append(f"| {env} | " + " | ".join(cells) + " |")
    return [*lines, ""]
