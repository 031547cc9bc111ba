"""Trajectory-following module (thesis §3.5.3, App. B.2.2, B.2.4).

A follower turns the tracking point chosen by :func:`select_tracking_index` into one low-level
action of the wrapped robot. Two kinds:

* :class:`ProportionalFollower` -- the thesis' controller for the omnidirectional Mass robot
  (its public code: action = 8 x the vector to the waypoint). Mass actions are world-frame
  position deltas, so the vector is used in the world frame.
* :class:`PolicyFollower` -- a goal-conditioned policy (trained with SAC, obstacle-free, goals
  d_min..2 d_min away, reward Eq. 3.9) for Point and Car. Its input is the robot's own sensors
  plus the goal in the robot frame; see :mod:`semdp.embedded.goal_reaching`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from semdp.embedded.follower_weights import load_follower_actor
from semdp.embedded.tracking import world_to_ego

#: Committed follower weights (``point.pt``, ``car.pt``; see ``weights/README.md``).
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
#: Robots of the Safety Gym replica and their default follower kind.
ROBOTS: tuple[str, ...] = ("point", "car", "mass")


class Follower(Protocol):
    """Maps (low-level observation, robot pose, target point) to one robot action."""

    def act(
        self, obs: np.ndarray, robot_position: np.ndarray, robot_heading: float, target: np.ndarray
    ) -> np.ndarray:
        """Return the low-level action that moves the robot root towards ``target``."""
        ...


class ProportionalFollower:
    """P-controller on the world-frame vector to the target (Mass robot, thesis code: gain 8).

    Args:
        gain: action per metre of error; the action is clipped to [-1, 1] per axis.
        frame: ``"world"`` for robots whose action is a world-frame displacement (Mass), ``"ego"``
            for robots that take body-frame velocity commands.
    """

    def __init__(self, gain: float = 8.0, frame: str = "world") -> None:
        if not gain > 0:
            raise ValueError(f"gain must be > 0, got {gain}")
        if frame not in ("world", "ego"):
            raise ValueError(f"frame must be 'world' or 'ego', got {frame!r}")
        self.gain = float(gain)
        self.frame = frame

    def act(
        self, obs: np.ndarray, robot_position: np.ndarray, robot_heading: float, target: np.ndarray
    ) -> np.ndarray:
        """Action = clip(gain * (target - position))."""
        error = np.asarray(target, dtype=np.float64) - np.asarray(robot_position, dtype=np.float64)
        if self.frame == "ego":
            error = world_to_ego(error, robot_heading)
        return np.clip(self.gain * error, -1.0, 1.0).astype(np.float32)


def follower_observation(
    sensors: np.ndarray, robot_position: np.ndarray, robot_heading: float, target: np.ndarray
) -> np.ndarray:
    """Input of a goal-conditioned follower: robot sensors followed by the ego-frame goal vector."""
    ego = world_to_ego(np.asarray(target, dtype=np.float64) - robot_position, robot_heading)
    return np.concatenate([np.asarray(sensors, dtype=np.float32), ego.astype(np.float32)])


class PolicyFollower:
    """A trained goal-reaching policy (deterministic mean action), loaded from a weights file.

    The file is written by :func:`semdp.embedded.follower_weights.export_follower` and holds a small
    MLP (``torch.save`` of a dict with ``state_dict``, ``obs_dim``, ``act_dim``, ``hidden_sizes``,
    ``sensor_slices`` and ``obs_mean``/``obs_std`` if the policy normalised its input).

    Args:
        weights: path to the exported follower weights; a relative path that does not exist
            is looked up in :data:`WEIGHTS_DIR` (so ``"point.pt"`` names the committed file).
        sensor_slices: names of the observation parts that make up the sensor vector; read from
            the weights file when omitted.
    """

    def __init__(self, weights: str | Path, sensor_slices: list[str] | None = None) -> None:

        weights = Path(weights)
        if not weights.is_absolute() and not weights.exists():
            weights = WEIGHTS_DIR / weights
        self.weights = weights
        self.actor, meta = load_follower_actor(weights)
        self.sensor_slices: list[str] = list(sensor_slices or meta["sensor_slices"])
        self.obs_mean = np.asarray(meta.get("obs_mean", 0.0), dtype=np.float32)
        self.obs_std = np.asarray(meta.get("obs_std", 1.0), dtype=np.float32)
        self.obs_clip = float(meta.get("obs_clip", np.inf))
        self._slices: list[slice] | None = None

    def bind(self, obs_slices: dict[str, slice]) -> None:
        """Resolve the sensor part of the environment's flat observation."""
        missing = [name for name in self.sensor_slices if name not in obs_slices]
        if missing:
            raise ValueError(
                f"follower expects sensors {missing} that the env does not observe; "
                f"env has {sorted(obs_slices)}"
            )
        self._slices = [obs_slices[name] for name in self.sensor_slices]

    def sensor_columns(self) -> np.ndarray:
        """Indices of the sensor entries in the env's flat observation, in input order (what
        :meth:`network_input` concatenates)."""
        if self._slices is None:
            raise RuntimeError("PolicyFollower.bind(env.obs_slices) must be called first")
        return np.concatenate([np.arange(s.start, s.stop, s.step or 1) for s in self._slices])

    def network_input(
        self, obs: np.ndarray, robot_position: np.ndarray, robot_heading: float, target: np.ndarray
    ) -> np.ndarray:
        """The policy's normalised input for ``target`` (float32, shape ``(obs_dim,)``)."""
        if self._slices is None:
            raise RuntimeError("PolicyFollower.bind(env.obs_slices) must be called first")
        sensors = np.concatenate([obs[s] for s in self._slices])
        x = follower_observation(sensors, robot_position, robot_heading, target)
        return np.clip((x - self.obs_mean) / self.obs_std, -self.obs_clip, self.obs_clip)

    def act(
        self, obs: np.ndarray, robot_position: np.ndarray, robot_heading: float, target: np.ndarray
    ) -> np.ndarray:
        """Deterministic action of the goal-conditioned policy for ``target``."""
        x = self.network_input(obs, robot_position, robot_heading, target)
        with torch.no_grad():
            action = self.actor(torch.as_tensor(x, dtype=torch.float32)[None])[0]
        return action.numpy()


def default_follower(robot: str, weights: str | Path | None = None) -> Follower:
    """The committed follower of ``robot``: SAC weights (Point, Car) or the P-controller (Mass)."""
    if robot not in ROBOTS:
        raise ValueError(f"robot must be one of {ROBOTS}, got {robot!r}")
    if robot == "mass":
        return ProportionalFollower(gain=8.0)
    return PolicyFollower(weights or WEIGHTS_DIR / f"{robot}.pt")
