"""Running mean/std observation normalisation (OmniSafe/CleanRL style)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt


class RunningNormalizer:
    """Normalise observations by running statistics and clip the result.

    Statistics use the parallel (Chan et al.) update over batches. ``enabled=False`` turns the
    normaliser into the identity while keeping the same interface.

    Args:
        shape: observation shape.
        clip: absolute clip on normalised values.
        epsilon: variance floor.
        enabled: whether to normalise at all.
    """

    def __init__(
        self, shape: tuple[int, ...], clip: float = 5.0, epsilon: float = 1e-8, enabled: bool = True
    ) -> None:
        if clip <= 0:
            raise ValueError(f"clip must be > 0, got {clip}")
        self.enabled = enabled
        self.clip = clip
        self.epsilon = epsilon
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = 1e-4

    def update(self, batch: npt.ArrayLike) -> None:
        """Fold a batch ``(n, *shape)`` into the statistics."""
        if not self.enabled:
            return
        x = np.asarray(batch, dtype=np.float64)
        b_mean, b_var, b_count = x.mean(axis=0), x.var(axis=0), x.shape[0]
        delta = b_mean - self.mean
        total = self.count + b_count
        self.mean = self.mean + delta * b_count / total
        m2 = self.var * self.count + b_var * b_count + delta**2 * self.count * b_count / total
        self.var = m2 / total
        self.count = total

    def __call__(self, obs: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """Normalised, clipped observations as float32."""
        x = np.asarray(obs, dtype=np.float64)
        if self.enabled:
            x = np.clip((x - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip, self.clip)
        return x.astype(np.float32)

    def state_dict(self) -> dict[str, Any]:
        """Statistics."""
        return {"mean": self.mean.copy(), "var": self.var.copy(), "count": self.count}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.mean = np.array(state["mean"], dtype=np.float64)
        self.var = np.array(state["var"], dtype=np.float64)
        self.count = float(state["count"])
