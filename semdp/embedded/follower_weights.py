"""Follower weights on disk (thesis App. B.2.4): the goal-reaching actor's MLP and the metadata
that :class:`semdp.embedded.follower.PolicyFollower` needs to rebuild it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from semdp.common.policy_files import load_data


def export_follower(
    actor_state: dict[str, Any], meta: dict[str, Any], path: str | Path
) -> Path:
    """Save a follower (actor weights + the metadata :func:`load_follower_actor` needs)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"state_dict": actor_state, **meta}, path)
    return path


def load_follower_actor(path: str | Path):
    """Load a follower exported by :func:`export_follower` (as data, never running code the
    file carries: :mod:`semdp.common.policy_files`); returns (actor, metadata)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"follower weights not found at {path}; train them with the command in "
            "semdp/embedded/weights/README.md"
        )
    payload = load_data(path, "follower weights")
    hidden = list(payload["hidden_sizes"])
    activation = {"relu": torch.nn.ReLU, "tanh": torch.nn.Tanh}[payload.get("activation", "relu")]
    layers: list[torch.nn.Module] = []
    width = int(payload["obs_dim"])
    for size in hidden:
        layers += [torch.nn.Linear(width, size), activation()]
        width = size
    layers.append(torch.nn.Linear(width, int(payload["act_dim"])))
    # SAC followers squash the mean with tanh; a Gaussian (PPO) policy's mean is clipped.
    layers.append(torch.nn.Tanh() if payload.get("output", "tanh") == "tanh"
                  else torch.nn.Hardtanh())
    actor = torch.nn.Sequential(*layers)
    actor.load_state_dict(payload["state_dict"])
    actor.eval()
    meta = {key: value for key, value in payload.items() if key != "state_dict"}
    return actor, meta
