"""Random layout sampling with keepouts (Safety-Gymnasium, Safety-Gymnasium's ``random_generator``).

Objects are placed in the task's order; each is drawn uniformly from the extents shrunk by its
keepout and accepted if it is at least ``k + k_j`` from every object placed before it. Each
object gets 100 draws and the whole layout 10000 attempts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from sims.safety_gym.config import ObjectSpec

Point2 = tuple[float, float]
PLACEMENT_DRAWS = 100
LAYOUT_ATTEMPTS = 10000
GOAL_DRAWS = 10000


class LayoutError(RuntimeError):
    """No layout satisfying the keepouts was found."""


def _first_clear(
    rng: np.random.Generator,
    extents: Sequence[float],
    keepout: float,
    placed: Sequence[tuple[float, float, float]],
    draws: int,
) -> Point2 | None:
    """The first of ``draws`` uniform draws that keeps clear of ``placed`` (``None`` if none).

    Draws come from the env's generator in batches of 32 points; the checks are plain Python,
    which beats numpy on these few-element comparisons.
    """
    xmin, ymin, xmax, ymax = extents
    x0, y0 = xmin + keepout, ymin + keepout
    sx, sy = xmax - xmin - 2 * keepout, ymax - ymin - 2 * keepout
    left = draws
    while left > 0:
        batch = min(left, 32)
        left -= batch
        values = rng.random(2 * batch).tolist()
        for j in range(batch):
            cx, cy = x0 + sx * values[2 * j], y0 + sy * values[2 * j + 1]
            for qx, qy, qk in placed:
                if (cx - qx) ** 2 + (cy - qy) ** 2 < (keepout + qk) ** 2:
                    break
            else:
                return (cx, cy)
    return None


def sample_layout(
    rng: np.random.Generator,
    extents: Sequence[float],
    objects: Mapping[str, ObjectSpec],
    fixed: Mapping[str, Sequence[Sequence[float]]] | None = None,
) -> dict[str, list[Point2]]:
    """Sample positions for every object type (Safety-Gymnasium 1.0.0).

    Args:
        rng: the env's generator (a seed fixes the layout).
        extents: ``(xmin, ymin, xmax, ymax)``.
        objects: object types in placement order with counts and keepouts.
        fixed: optional planted positions per type; they replace the sampled ones (their count
            may differ from Safety-Gymnasium's) and the others keep clear of them.

    Returns:
        Positions per type, ``{"agent": [(x, y)], "goal": [...], "hazards": [...], ...}``.

    Raises:
        LayoutError: if no layout is found in 10000 attempts.
    """
    fixed = dict(fixed or {})
    planted = [
        (float(p[0]), float(p[1]), objects[kind].keepout if kind in objects else 0.0)
        for kind, points in fixed.items()
        for p in points
    ]
    for _ in range(LAYOUT_ATTEMPTS):
        placed = list(planted)
        layout: dict[str, list[Point2]] = {}
        ok = True
        for kind, spec in objects.items():
            if kind in fixed:
                layout[kind] = [(float(p[0]), float(p[1])) for p in fixed[kind]]
                continue
            points: list[Point2] = []
            for _i in range(spec.count):
                p = _first_clear(rng, extents, spec.keepout, placed, PLACEMENT_DRAWS)
                if p is None:
                    ok = False
                    break
                points.append(p)
                placed.append((p[0], p[1], spec.keepout))
            if not ok:
                break
            layout[kind] = points
        if ok:
            return layout
    raise LayoutError(f"no layout satisfies the keepouts after {LAYOUT_ATTEMPTS} attempts")


def sample_goal(
    rng: np.random.Generator,
    extents: Sequence[float],
    keepout: float,
    placed: Sequence[tuple[float, float, float]],
) -> Point2 | None:
    """Resample the goal against the current objects ``(x, y, keepout)`` (Safety-Gymnasium 1.0.0).

    Returns:
        The new goal, or ``None`` after 10000 failed draws (the episode then terminates).
    """
    return _first_clear(rng, extents, keepout, placed, GOAL_DRAWS)
