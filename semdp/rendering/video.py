"""Write recorded frames as MP4 (imageio with imageio-ffmpeg, the optional extra ``video``,
which ships its own ffmpeg) or, without it, as a GIF (PIL, ``sims.rendering.save_gif``)."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sims.rendering import save_gif


def mp4_available() -> bool:
    """Whether imageio and imageio-ffmpeg are importable."""
    return all(importlib.util.find_spec(m) is not None for m in ("imageio", "imageio_ffmpeg"))


def write_video(frames: Sequence[np.ndarray], stem: Path, fps: float) -> Path:
    """``stem.mp4`` (H.264, yuv420p) when :func:`mp4_available`, else ``stem.gif``.

    Raises:
        ValueError: no frames, or a non-positive fps.
    """
    if len(frames) == 0:
        raise ValueError("write_video: no frames given")
    if not fps > 0:
        raise ValueError(f"write_video: fps must be positive, got {fps}")
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    if not mp4_available():
        return save_gif(frames, stem.with_suffix(".gif"), fps=fps)
    import imageio.v2 as imageio

    path = stem.with_suffix(".mp4")
    with imageio.get_writer(path, fps=fps, codec="libx264", macro_block_size=16,
                            ffmpeg_log_level="error") as writer:
        for frame in frames:
            writer.append_data(np.asarray(frame, dtype=np.uint8))
    return path
