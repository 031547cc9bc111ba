"""Seeding and RNG-state capture, so that a resumed run replays an uninterrupted one exactly."""

from __future__ import annotations

import random
from typing import Any

import numpy as np
import torch


def seed_everything(seed: int) -> None:
    """Seed Python's, NumPy's and torch's global generators.

    Args:
        seed: non-negative integer seed.
    """
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    random.seed(seed)
    np.random.seed(seed)  # noqa: NPY002  (legacy global RNG, seeded for third-party code)
    torch.manual_seed(seed)


def get_rng_states() -> dict[str, Any]:
    """Snapshot of the global Python, NumPy and torch (CPU) generator states."""
    return {
        "python": random.getstate(),
        "numpy": np.random.get_state(),  # noqa: NPY002
        "torch": torch.get_rng_state(),
    }


def set_rng_states(states: dict[str, Any]) -> None:
    """Restore a snapshot taken by :func:`get_rng_states`."""
    random.setstate(states["python"])
    np.random.set_state(states["numpy"])  # noqa: NPY002
    torch.set_rng_state(states["torch"])
