"""Rendering helpers shared by the simulators: numpy frames to GIF (PIL, imported lazily)."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)


def save_gif(frames: Sequence[np.ndarray], path: str | Path, fps: float = 25.0) -> Path:
    """Write ``(H, W, 3)`` uint8 frames to an animated GIF that loops forever.

    Args:
        frames: equally sized RGB frames (e.g. from ``env.render()``).
        path: output file; parent folders are created.
        fps: playback rate (GIF delays are rounded to 10 ms).

    Returns:
        The path written.

    Raises:
        ValueError: for no frames, mixed sizes, a wrong frame shape or a non-positive fps.
    """
    from PIL import Image

    if len(frames) == 0:
        raise ValueError("save_gif: no frames given")
    if not fps > 0:
        raise ValueError(f"save_gif: fps must be positive, got {fps}")
    shape = np.asarray(frames[0]).shape
    if len(shape) != 3 or shape[2] != 3:
        raise ValueError(f"save_gif: frames must be (H, W, 3), got {shape}")
    images = []
    for k, frame in enumerate(frames):
        arr = np.asarray(frame)
        if arr.shape != shape:
            raise ValueError(f"save_gif: frame {k} has shape {arr.shape}, expected {shape}")
        images.append(Image.fromarray(arr.astype(np.uint8), mode="RGB"))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    duration_ms = max(10, round(1000.0 / fps / 10) * 10)
    images[0].save(
        path, save_all=True, append_images=images[1:], duration=duration_ms, loop=0, optimize=False
    )
    logger.info("wrote %d frames to %s", len(images), path)
    return path
