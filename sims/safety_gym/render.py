"""Top-down ``rgb_array`` frames of a Safety Gym scene (PIL, imported lazily).

Colours: hazards blue discs, vases teal squares, pillars dark-blue discs, push box yellow,
goal green disc (translucent ring), buttons orange (the goal button ringed green), gremlins
purple squares, the robot red with a white heading line from its root; a caller's overlay
(planned waypoints and subgoal) is drawn in black/magenta on top.

The drawing reads the scene through :class:`TopDownScene` (the attributes a
:class:`~sims.safety_gym.env.SafetyGymEnv` has), so this module does not import the env.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import pymunk

from sims.safety_gym.config import LevelSpec


class TopDownScene(Protocol):
    """What :func:`render_topdown` reads: object positions and sizes, bodies, the robot pose."""

    layout_spec: LevelSpec
    task: str
    hazards: list[tuple[float, float]]
    hazard_radius: float
    pillars: list[tuple[float, float]]
    pillar_radius: float
    buttons: list[tuple[float, float]]
    goal_button: int
    goal_x: float
    goal_y: float
    goal_size: float
    vase_bodies: list[pymunk.Body]
    gremlin_bodies: list[pymunk.Body]
    box_body: pymunk.Body | None
    body: pymunk.Body
    robot_scale: float

    @property
    def robot_forward_heading(self) -> float:
        """Yaw of the driving direction (rad)."""
        ...


COLOURS = {
    "floor": (235, 235, 230),
    "grid": (215, 215, 210),
    "extent": (190, 190, 185),
    "hazards": (70, 110, 230),
    "vases": (30, 170, 170),
    "pillars": (40, 40, 120),
    "push_box": (225, 185, 40),
    "goal": (60, 190, 60),
    "buttons": (240, 140, 30),
    "gremlins": (150, 60, 190),
    "robot": (210, 40, 40),
    "heading": (255, 255, 255),
    "path": (20, 20, 20),
    "subgoal": (230, 0, 200),
}


def render_topdown(
    env: TopDownScene,
    size: int = 256,
    waypoints: np.ndarray | None = None,
    subgoal: Sequence[float] | None = None,
) -> np.ndarray:
    """Draw the current state; the view covers the placement extents plus 1 m of margin.

    Args:
        env: the scene (a :class:`~sims.safety_gym.env.SafetyGymEnv`).
        size: frame side in pixels.
        waypoints: optional planned path ``(n, 2)``, drawn in black.
        subgoal: optional subgoal ``(x, y)``, drawn as a magenta cross.
    """
    from PIL import Image, ImageDraw

    xmin, ymin, xmax, ymax = env.layout_spec.extents
    half = max(xmax - xmin, ymax - ymin) / 2 + 1.0
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    scale = size / (2 * half)

    def px(x: float, y: float) -> tuple[float, float]:
        return ((x - cx + half) * scale, (cy + half - y) * scale)

    def disc(draw, x, y, r, fill, outline=None, width=1):
        (u, v), rr = px(x, y), r * scale
        draw.ellipse([u - rr, v - rr, u + rr, v + rr], fill=fill, outline=outline, width=width)

    image = Image.new("RGB", (size, size), COLOURS["floor"])
    draw = ImageDraw.Draw(image)
    for g in range(math.floor(cx - half), math.ceil(cx + half) + 1):
        draw.line([px(g, cy - half), px(g, cy + half)], fill=COLOURS["grid"])
    for g in range(math.floor(cy - half), math.ceil(cy + half) + 1):
        draw.line([px(cx - half, g), px(cx + half, g)], fill=COLOURS["grid"])
    draw.rectangle([px(xmin, ymax), px(xmax, ymin)], outline=COLOURS["extent"])

    for x, y in env.hazards:
        disc(draw, x, y, env.hazard_radius, COLOURS["hazards"])
    if env.task != "button":
        disc(draw, env.goal_x, env.goal_y, env.goal_size, None, COLOURS["goal"], 2)
        disc(draw, env.goal_x, env.goal_y, 0.05, COLOURS["goal"])
    for k, (x, y) in enumerate(env.buttons):
        disc(draw, x, y, 0.1, COLOURS["buttons"])
        if k == env.goal_button:
            disc(draw, x, y, env.goal_size, None, COLOURS["goal"], 3)
    for x, y in env.pillars:
        disc(draw, x, y, env.pillar_radius, COLOURS["pillars"])

    def body_shapes(body: pymunk.Body, colour) -> None:
        for shape in body.shapes:
            if isinstance(shape, pymunk.Circle):
                p = body.local_to_world(shape.offset)
                disc(draw, p.x, p.y, shape.radius, colour)
            elif isinstance(shape, pymunk.Poly):
                pts = [px(*body.local_to_world(v)) for v in shape.get_vertices()]
                draw.polygon(pts, fill=colour)

    for body in env.vase_bodies:
        body_shapes(body, COLOURS["vases"])
    for body in env.gremlin_bodies:
        body_shapes(body, COLOURS["gremlins"])
    if env.box_body is not None:
        body_shapes(env.box_body, COLOURS["push_box"])
    body_shapes(env.body, COLOURS["robot"])
    rx, ry = env.body.position
    yaw = env.robot_forward_heading
    tip = 0.18 * env.robot_scale  # past the Point's nose (0.15), the Car's bumper (0.175)
    draw.line([px(rx, ry), px(rx + tip * math.cos(yaw), ry + tip * math.sin(yaw))],
              fill=COLOURS["heading"], width=max(1, size // 128))  # fmt: skip
    disc(draw, rx, ry, 0.025, COLOURS["heading"])

    if waypoints is not None and len(waypoints):
        pts = [px(float(x), float(y)) for x, y in waypoints]
        if len(pts) > 1:
            draw.line(pts, fill=COLOURS["path"], width=max(1, size // 200))
        for u, v in pts:
            draw.ellipse([u - 1.5, v - 1.5, u + 1.5, v + 1.5], fill=COLOURS["path"])
    if subgoal is not None:
        u, v = px(*map(float, subgoal))
        r = max(3.0, 0.06 * scale)
        draw.line([u - r, v - r, u + r, v + r], fill=COLOURS["subgoal"], width=2)
        draw.line([u - r, v + r, u + r, v - r], fill=COLOURS["subgoal"], width=2)
    return np.asarray(image, dtype=np.uint8)
