"""Annotations on a top-down frame of a ``sims`` Safety Gym env (``render_topdown`` in
``sims/safety_gym/render.py`` draws the true objects and the planned path).

Added here: the obstacles the planner *perceived* (orange crosses with their eps' ring, beside the
true hazards and pillars the renderer draws), a red frame and a red ring round the robot on steps
with cost, and a line of text with the step, return and cost so far.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

PERCEIVED = (255, 140, 0)
COST = (230, 20, 20)
TEXT_BACKGROUND = (255, 255, 255)
TEXT = (0, 0, 0)


@dataclass(frozen=True)
class FrameNotes:
    """What is drawn on one frame.

    Attributes:
        step: low-level steps since the reset.
        episode_return, episode_cost: sums so far.
        cost_now: a step since the previous frame had cost.
        perceived: the planner's obstacles ``(m, 3)`` [x, y, r], or ``None``.
        clearance: the planner's eps' (ring radius around each perceived obstacle), or ``None``.
    """

    step: int
    episode_return: float
    episode_cost: float
    cost_now: bool
    perceived: np.ndarray | None = None
    clearance: float | None = None


def world_to_pixel(scene: object, size: int) -> tuple[Callable[[float, float], tuple[float, float]],
                                                      float] | None:
    """The pixel transform of ``render_topdown`` (the placement extents plus 1 m of margin) and
    the pixels per metre, or ``None`` for a scene without ``layout_spec.extents``."""
    spec = getattr(scene, "layout_spec", None)
    extents = getattr(spec, "extents", None)
    if extents is None:
        return None
    xmin, ymin, xmax, ymax = (float(v) for v in extents)
    half = max(xmax - xmin, ymax - ymin) / 2 + 1.0
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    scale = size / (2 * half)

    def px(x: float, y: float) -> tuple[float, float]:
        return ((x - cx + half) * scale, (cy + half - y) * scale)

    return px, scale


def annotate(frame: np.ndarray, scene: object, notes: FrameNotes) -> np.ndarray:
    """A copy of ``frame`` (``(H, W, 3)`` uint8) with ``notes`` drawn on it."""
    from PIL import Image, ImageDraw

    image = Image.fromarray(np.asarray(frame, dtype=np.uint8), mode="RGB")
    draw = ImageDraw.Draw(image)
    size = image.width
    width = max(2, size // 170)
    transform = world_to_pixel(scene, size)
    if transform is not None:
        px, scale = transform
        if notes.perceived is not None:
            for x, y, r in np.asarray(notes.perceived, dtype=np.float64).reshape(-1, 3):
                u, v = px(x, y)
                ring = (r + (notes.clearance or 0.0)) * scale
                if ring > 0:
                    draw.ellipse([u - ring, v - ring, u + ring, v + ring], outline=PERCEIVED,
                                 width=max(1, width // 2))
                arm = max(3.0, 0.05 * scale)
                draw.line([u - arm, v - arm, u + arm, v + arm], fill=PERCEIVED, width=width)
                draw.line([u - arm, v + arm, u + arm, v - arm], fill=PERCEIVED, width=width)
        body = getattr(scene, "body", None)
        if notes.cost_now and body is not None:
            u, v = px(float(body.position[0]), float(body.position[1]))
            ring = 0.3 * scale
            draw.ellipse([u - ring, v - ring, u + ring, v + ring], outline=COST, width=width)
    if notes.cost_now:
        border = max(4, size // 64)
        draw.rectangle([0, 0, size - 1, image.height - 1], outline=COST, width=border)
    text = (f"t {notes.step}  return {notes.episode_return:.2f}  cost {notes.episode_cost:.0f}"
            + ("  COST" if notes.cost_now else ""))
    left, top, right, bottom = draw.textbbox((8, 8), text)
    draw.rectangle([left - 3, top - 2, right + 3, bottom + 2], fill=TEXT_BACKGROUND)
    draw.text((8, 8), text, fill=COST if notes.cost_now else TEXT)
    return np.asarray(image, dtype=np.uint8)
