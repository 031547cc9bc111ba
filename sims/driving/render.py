"""Top-down ``rgb_array`` rendering of the driving tasks (road, car with heading, recent path).

PIL is imported lazily here so that importing :mod:`sims` stays light. The drawing reads the
scene through :class:`DrivingScene` (the attributes a :class:`~sims.driving.base.DrivingEnv`
has), so this module does not import the env.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from sims.driving.tracks import CircleTrack, RandomPathTrack
from sims.driving.vehicle import BicycleModel


class DrivingScene(Protocol):
    """What :func:`render_top_down` reads: the track, the road, the car and its trail."""

    track: CircleTrack | RandomPathTrack
    model: BicycleModel
    road_width: float
    half_width: float
    termination_distance: float
    trail: list[tuple[float, float]]

    @property
    def vehicle_state(self) -> tuple[float, float, float, float, float, float]:
        """``(x, y, psi, v_x, v_y, r)``."""
        ...

    @property
    def frenet(self) -> tuple[float, float, float, float]:
        """``(s, d, path_heading, curvature)``."""
        ...

IMAGE_SIZE = 400
TRAJECTORY_VIEW_HALF_EXTENT = 4.0
GRASS = (86, 140, 72)
ASPHALT = (70, 70, 76)
CENTRE_LINE = (235, 220, 120)
TRAIL = (90, 170, 255)
CAR_BODY = (220, 50, 50)
CAR_NOSE = (255, 255, 255)


def render_top_down(env: DrivingScene, size: int = IMAGE_SIZE) -> np.ndarray:
    """Draw ``env`` from above.

    The Circle view is fixed on the whole circle; the Trajectory view follows the car
    (+-4 m around it).

    Args:
        env: The driving env (unwrapped).
        size: Image side in pixels.

    Returns:
        ``uint8`` array of shape ``(size, size, 3)``.
    """
    from PIL import Image, ImageDraw

    x, y, psi, _, _, _ = env.vehicle_state
    track = env.track
    if isinstance(track, CircleTrack):
        centre_x, centre_y = 0.0, 0.0
        half_extent = track.radius + env.termination_distance + 0.3
    else:
        centre_x, centre_y = x, y
        half_extent = TRAJECTORY_VIEW_HALF_EXTENT
    scale = size / (2.0 * half_extent)

    def to_pixel(px: float, py: float) -> tuple[float, float]:
        return (px - centre_x + half_extent) * scale, (half_extent - (py - centre_y)) * scale

    image = Image.new("RGB", (size, size), GRASS)
    draw = ImageDraw.Draw(image)
    road_px = max(1, round(env.road_width * scale))
    if isinstance(track, CircleTrack):
        for radius, colour, width in ((track.radius + env.half_width, ASPHALT, road_px),
                                      (track.radius + 0.01, CENTRE_LINE, 2)):
            (x0, y0), (x1, y1) = to_pixel(-radius, radius), to_pixel(radius, -radius)
            draw.ellipse((x0, y0, x1, y1), outline=colour, width=width)
    else:
        s_car = env.frenet[0]
        reach = 1.5 * half_extent
        count = 80
        points = [to_pixel(*track.point_at(s_car - reach + 2 * reach * k / count))
                  for k in range(count + 1)]
        draw.line(points, fill=ASPHALT, width=road_px, joint="curve")
        draw.line(points, fill=CENTRE_LINE, width=2)

    if len(env.trail) > 1:
        draw.line([to_pixel(px, py) for px, py in env.trail], fill=TRAIL, width=2)

    params = env.model.params
    c, s = math.cos(psi), math.sin(psi)
    half_l, half_w = 0.5 * params.body_length, 0.5 * params.body_width
    corners = [(half_l, half_w), (-half_l, half_w), (-half_l, -half_w), (half_l, -half_w)]
    body = [to_pixel(x + c * bx - s * by, y + s * bx + c * by) for bx, by in corners]
    draw.polygon(body, fill=CAR_BODY)
    nose = [(half_l, 0.0), (0.2 * half_l, 0.7 * half_w), (0.2 * half_l, -0.7 * half_w)]
    draw.polygon([to_pixel(x + c * bx - s * by, y + s * bx + c * by) for bx, by in nose],
                 fill=CAR_NOSE)
    return np.asarray(image, dtype=np.uint8)
