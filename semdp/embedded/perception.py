"""Obstacle perception for the planner and the safety filter: LiDAR reconstruction (thesis
default) or ground truth.

What is an obstacle (a cost region), by kind: hazards, vases, pillars and gremlins (thesis
§3.6.1: not the box, not the goal) and, in the Button tasks (beyond the thesis, whose
experiments are Goal and Push), every button **but the goal button**: touching another button
costs (``cost_buttons``), the goal button must be pressed. Two properties of the Button task need
more than a snapshot of the LiDAR:

* **Buttons and the goal.** The goal is the goal button's centre, so the goal LiDAR channel is
  that button's contribution to the buttons channel, bin for bin (same position, same
  arithmetic). :func:`button_frame` zeroes the button bins whose reading equals the goal
  channel's: what remains is lit by the other buttons (a bin where a nearer wrong button hides
  the goal button keeps its reading). A wrong button that the goal button's reading hides in
  one of its bins (farther, as any LiDAR hides a farther object of a kind in a bin) is seen
  again once the robot's bearing to the two differs by a bin. Ground truth drops the button at
  the goal position.
* **The grace period.** After a press the goal moves to another button and for
  ``BUTTON_RESAMPLING_DELAY`` (10) steps the wrong-button cost is off and the buttons channel is
  blank. The safety layer does not use the relief: every non-goal button stays a cost region
  throughout, the just-pressed one included (the robot starts the grace touching it, inside its
  region, and the planner's and the filter's escape modes take it out before the timer ends).
  Buttons never move, so a blank channel is read from a :class:`ButtonMemory`: the last lit
  frame of the episode with the pose it was taken from, in world coordinates. That frame is read
  whole (its goal may be the button just pressed), so the new goal button is a cost region until
  the channel lights again: at most 10 steps.

Gremlins move. **The stated assumption** of the safety layer is Safety Gym's gremlin law as the
replica implements it (``sims/safety_gym/world.py`` ``_move_gremlins``): each gremlin tracks a
target circling its placement ("home") at 0.35 m and 1 rad/s, ``home + 0.35 (sin t, cos t)`` at
episode time ``t``, with a first-order lag of 0.09 s, starting at home. Every gremlin then sits
at ``home + o(t)`` with the same offset ``o(t)`` (:func:`gremlin_offset`: the lag's closed-form
response, within 1.7 mm of the simulator's substep law; ``|o(t)| <= 0.35`` m), so a gremlin seen
at ``g`` has its home at ``g - o(t)``, and everywhere it will ever be lies within
:data:`GREMLIN_ORBIT` (0.35 m + :data:`GREMLIN_LAW_TOLERANCE`) of that home. The planner and the
filter treat each gremlin as that **static orbit disc** (:func:`gremlin_orbits`): a robot outside
it can never be touched, so the machinery of the static hazards (certificates, braking, escape
modes) covers the gremlins too, from one LiDAR reading (the bin's position shifted by ``-o(t)``)
as from ground truth. The price is room: a wrong or goal button inside a gremlin's orbit disc is
out of bounds (timing a pass between two visits of the gremlin would need the speed as well as
the law). tests/test_button_safety.py checks the law against the simulator and plants robots
driven into a gremlin's orbit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sims.safety_gym.perception import obstacles_from_lidar

#: Object types the planner and the filter avoid (thesis §3.6.1: not the box, not the goal;
#: buttons: every button but the goal button).
OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins", "buttons")

#: ``lidar``: the thesis' reconstruction (bin-centre bearing); ``lidar_refined``: the same peaks
#: at the bearing implied by the aliasing of the neighbouring bins (exact for an isolated object;
#: beyond the thesis); ``gt``: the simulator's ground truth ("Ours w/ gt").
PERCEPTION_MODES: tuple[str, ...] = ("lidar", "lidar_refined", "gt")

#: How the safety layer treats gremlins (``env.gremlins``): ``"orbit"``, each one's whole orbit
#: disc; ``"moving"``, where the law puts it (the planner: where it is now, the thesis' snapshot;
#: the filter: at each step of a certified plan, :mod:`semdp.embedded.moving_certificate`).
GREMLIN_MODELS: tuple[str, ...] = ("orbit", "moving")

#: The gremlin law (module docstring): the target's distance from home (m), its angular speed is
#: 1 rad/s, and the tracking lag (s).
GREMLIN_TRAVEL = 0.35
GREMLIN_LAG_S = 0.09
#: How far (m) the simulator's substep law may be from :func:`gremlin_offset` (measured: 1.7 mm).
GREMLIN_LAW_TOLERANCE = 0.005
#: The radius (m) around a gremlin's home that holds every position its centre will ever take.
GREMLIN_ORBIT = GREMLIN_TRAVEL + GREMLIN_LAW_TOLERANCE
#: A button reading at most this far from the goal channel's is the goal button's.
_SAME_READING = 1e-9


def gremlin_offset(t: float) -> np.ndarray:
    """Every gremlin's position relative to its home at episode time ``t`` (s): the first-order
    lag's response to the target ``0.35 (sin t, cos t)`` from rest at home, in closed form. In
    complex notation the target is ``0.35 i exp(-i t)``, the steady response that divided by
    ``1 - 0.09 i``, and the start-up transient decays as ``exp(-t / 0.09)``."""
    t = max(float(t), 0.0)

    def steady(s: float) -> complex:
        return GREMLIN_TRAVEL * 1j * complex(np.exp(-1j * s)) / (1.0 - 1j * GREMLIN_LAG_S)

    z = steady(t) - steady(0.0) * math.exp(-t / GREMLIN_LAG_S)
    return np.array([z.real, z.imag])


def gremlin_offsets(times: np.ndarray) -> np.ndarray:
    """``(len(times), 2)``: :func:`gremlin_offset` at each of ``times`` (s), on arrays (the
    same closed form; tests/test_moving_gremlins.py checks it against the scalar one)."""
    t = np.maximum(np.asarray(times, dtype=np.float64), 0.0)
    scale = GREMLIN_TRAVEL * 1j / (1.0 - 1j * GREMLIN_LAG_S)
    z = scale * np.exp(-1j * t) - scale * np.exp(-t / GREMLIN_LAG_S)
    return np.stack([z.real, z.imag], axis=-1)


def gremlin_orbits(found: np.ndarray, t: float) -> np.ndarray:
    """The orbit discs of gremlins seen at rows ``[x, y, r]`` at episode time ``t``: centred at
    their homes (``g - o(t)``), the radius grown by :data:`GREMLIN_ORBIT` (module docstring)."""
    orbits = np.array(found, dtype=np.float64).reshape(-1, 3)
    orbits[:, :2] -= gremlin_offset(t)
    orbits[:, 2] += GREMLIN_ORBIT
    return orbits


def episode_time(env: Any) -> float:
    """The env's episode time (its ``sim_time``; 0 if it has none)."""
    return float(getattr(env, "sim_time", 0.0))


@dataclass(frozen=True)
class LidarFrame:
    """One 16-bin LiDAR channel with the robot pose it was read from (world frame).

    ``whole``: the channel as the sensor gave it when ``readings`` has bins removed (the
    buttons' channel less the goal button's bins), None when ``readings`` is whole. The
    sensor's readings bound every object's aliasing contributions to its neighbour bins; a
    removed bin does not.
    """

    readings: np.ndarray
    position: np.ndarray
    heading: float
    whole: np.ndarray | None = None


class ButtonMemory:
    """The last lit buttons LiDAR frame of the current episode (module docstring: the channel is
    blank while the button timer runs; buttons never move, so an old frame stays true).

    :meth:`forget` at every reset; a frame also counts as stale when it belongs to another env
    or to a later step count than the env's (a new episode).
    """

    def __init__(self) -> None:
        self._frame: LidarFrame | None = None
        self._owner: int | None = None
        self._steps = -1

    def forget(self) -> None:
        """Drop the remembered frame (a new episode)."""
        self._frame, self._owner, self._steps = None, None, -1

    def remember(self, env: Any, frame: LidarFrame) -> None:
        """Keep ``frame``, read from ``env`` now."""
        self._frame, self._owner, self._steps = frame, id(env), int(getattr(env, "steps", 0))

    def recall(self, env: Any) -> LidarFrame | None:
        """The remembered frame if it is from ``env``'s current episode, else None."""
        if self._frame is None or self._owner != id(env) or \
                self._steps > int(getattr(env, "steps", 0)):
            return None
        return self._frame


def goal_free_button_readings(env: Any, obs: np.ndarray) -> np.ndarray:
    """The buttons LiDAR channel without the bins the goal button explains (module docstring)."""
    readings = np.array(obs[env.obs_slices["buttons_lidar"]], dtype=np.float64)
    if "goal_lidar" in env.obs_slices:
        goal = np.asarray(obs[env.obs_slices["goal_lidar"]], dtype=np.float64)
        readings[(goal > 0.0) & (np.abs(readings - goal) <= _SAME_READING)] = 0.0
    return readings


def button_frame(env: Any, obs: np.ndarray, memory: ButtonMemory | None = None
                 ) -> LidarFrame | None:
    """The buttons LiDAR frame to read the wrong buttons from, or None without buttons.

    The current channel, lit: its bins less the goal button's (``memory`` keeps the whole
    channel); blank: ``memory``'s frame of this episode, whole (module docstring).
    """
    if "buttons_lidar" not in env.obs_slices:
        return None
    raw = np.asarray(obs[env.obs_slices["buttons_lidar"]], dtype=np.float64)
    if raw.max() > 0.0:
        position = np.asarray(env.robot_position, dtype=np.float64)
        heading = float(env.robot_heading)
        if memory is not None:
            memory.remember(env, LidarFrame(raw.copy(), position, heading))
        return LidarFrame(goal_free_button_readings(env, obs), position, heading, raw)
    return memory.recall(env) if memory is not None else None


def wrong_buttons(env: Any) -> np.ndarray:
    """Ground truth: ``[x, y, r]`` of every button but the goal button."""
    buttons = np.asarray(env.obstacles(kinds=("buttons",)), dtype=np.float64).reshape(-1, 3)
    if not len(buttons):
        return buttons
    goal = np.asarray(env.goal_position, dtype=np.float64)
    return buttons[np.linalg.norm(buttons[:, :2] - goal, axis=1) > 1e-9]


def perceive_obstacles(
    env,
    obs: np.ndarray,
    mode: str = "lidar",
    kinds: tuple[str, ...] = OBSTACLE_KINDS,
    use_radii: bool = False,
    lidar_max_dist: float = 3.0,
    memory: ButtonMemory | None = None,
    gremlins: str = "orbit",
) -> np.ndarray:
    """Obstacles as an (m, 3) array of [x, y, radius] for the planner.

    Args:
        env: the unwrapped Safety Gym replica env (``robot_position``, ``robot_heading``,
            ``obs_slices``, ``obstacles``, ``goal_position``, ``sim_time``).
        obs: the env's current flat observation.
        mode: ``"lidar"`` reconstructs positions from each type's 16 LiDAR bins (the thesis'
            default, noisy: bin-centre angle, distance (1 - reading) * max);
            ``"lidar_refined"`` places each peak at the bearing its neighbours' aliasing implies
            (exact for an isolated object); ``"gt"`` reads the simulator's ground truth
            ("Ours w/ gt").
        kinds: object types that are obstacles (buttons: all but the goal button; gremlins:
            their orbit discs, :func:`gremlin_orbits`).
        use_radii: ground truth only: keep the objects' radii (clearance eps' + r). The thesis
            plans around centres (r = 0) and sets eps' = 0.5 m to cover the object sizes.
        lidar_max_dist: LiDAR range (Safety Gym: 3 m).
        memory: LiDAR only: the buttons channel's memory (read while the channel is blank,
            module docstring); None reads the current channel only.
        gremlins: ``"orbit"`` (each gremlin as the disc of its orbit, :func:`gremlin_orbits`)
            or ``"moving"`` (where it is now, the thesis' snapshot: for a filter that
            certifies against the gremlins' motion, :mod:`semdp.embedded.moving_certificate`).
    """
    if mode not in PERCEPTION_MODES:
        raise ValueError(f"perception mode must be one of {PERCEPTION_MODES}, got {mode!r}")
    rows = []
    for kind in kinds:
        if mode == "gt":
            if kind == "buttons":
                found = wrong_buttons(env)
            else:
                found = np.asarray(env.obstacles(kinds=(kind,)), dtype=np.float64).reshape(-1, 3)
            found = found.copy()
            if not use_radii:
                found[:, 2] = 0.0
        else:
            found = _lidar_obstacles(env, obs, kind, mode, lidar_max_dist, memory)
        if kind == "gremlins" and len(found) and gremlins == "orbit":
            found = gremlin_orbits(found, episode_time(env))
        if len(found):
            rows.append(found)
    if not rows:
        return np.zeros((0, 3))
    return np.concatenate(rows)


def _lidar_obstacles(env: Any, obs: np.ndarray, kind: str, mode: str, max_dist: float,
                     memory: ButtonMemory | None) -> np.ndarray:
    """``[x, y, 0]`` rows of one kind's LiDAR peaks (buttons: :func:`button_frame`)."""
    if kind == "buttons":
        frame = button_frame(env, obs, memory)
    elif f"{kind}_lidar" in env.obs_slices:
        frame = LidarFrame(obs[env.obs_slices[f"{kind}_lidar"]],
                           np.asarray(env.robot_position, dtype=np.float64),
                           float(env.robot_heading))
    else:
        frame = None
    if frame is None:
        return np.zeros((0, 3))
    found = obstacles_from_lidar(frame.readings, frame.position, frame.heading,
                                 max_dist=max_dist, refine_bearing=mode == "lidar_refined")
    found = np.asarray(found, dtype=np.float64).reshape(-1, 2)
    return np.hstack([found, np.zeros((len(found), 1))])
