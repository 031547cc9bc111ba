"""The cost regions of the low-level safety filter (beyond the thesis, §3.5.2): what
:class:`~semdp.embedded.shield.SafetyShield` keeps the robot's braking trajectory out of.

Cost regions are discs around the obstacles the planner sees, by kind: hazards cost when the
root node is inside them; vases, pillars, gremlins and the buttons other than the goal button
when the robot's outline touches them, i.e. the root within ``object radius + robot extent``
(:mod:`semdp.embedded.perception`: which button is the goal, the buttons' memory while their
LiDAR channel is blank after a press, and the grace period). A gremlin's region is the disc of
its orbit around its home, static under the stated gremlin law
(:func:`~semdp.embedded.perception.gremlin_orbits`): outside it the robot can never be touched,
so gremlins need nothing the static kinds do not.

With ``perception="lidar"`` the obstacles are re-read from the LiDAR at every checked step (the
buttons, while their channel is blank, from the last lit frame). A LiDAR bin gives an object's
range exactly but its bearing only to within half a bin (11.25°), so a region placed at the bin
centre can sit up to ``2 d sin(π/32) ≈ 0.196 d`` from the true object at range ``d``: more than
the margin beyond 0.26 m. ``lidar_bearing_bound`` says how the filter bounds that bearing
(:mod:`semdp.embedded.lidar_bounds`: by the neighbour bins' aliasing, the default; by the whole
bin; or not at all), under one stated law: an object the filter must see is the largest
contribution to its own bin. ``"gt"`` reads the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from semdp.embedded.lidar_bounds import (
    BEARING_ERROR_PER_METRE,
    LIDAR_RANGE,
    RANGE_TOLERANCE,
    bin_regions,
)
from semdp.embedded.perception import (
    GREMLIN_ORBIT,
    OBSTACLE_KINDS,
    ButtonMemory,
    LidarFrame,
    button_frame,
    episode_time,
    gremlin_offset,
    perceive_obstacles,
)

#: Kinds whose cost is a contact with the robot's outline: their regions add the robot's extent.
CONTACT_KINDS = ("vases", "pillars", "gremlins", "buttons")
#: Kinds whose LiDAR frame is more than the current channel: the buttons' (remembered while
#: blank, less the goal button) and the gremlins' (shifted to the orbit's centre).
_FRAMED_KINDS = ("buttons", "gremlins")
#: Each kind's LiDAR observation key.
_LIDAR_KEYS = {kind: f"{kind}_lidar" for kind in OBSTACLE_KINDS}


class Regions(NamedTuple):
    """Cost-region rows and, per row, what the filter knows of the object behind it."""

    #: ``(m, 3)`` rows ``[x, y, R]``: each disc holds its object's cost region plus the margin.
    rows: np.ndarray
    #: ``(m,)``: the cost is a contact with the robot's outline (``R`` holds the robot's extent).
    contact: np.ndarray
    #: ``(m,)``: a gremlin's orbit disc (inside it the gremlin may come, elsewhere on its orbit).
    orbit: np.ndarray
    #: ``(m,)`` m: how far the object's centre (a gremlin's home) may lie from the row's centre:
    #: the LiDAR bin's bearing allowance; 0 read from the simulator; ``inf`` unbounded.
    spread: np.ndarray
    #: ``(m,)`` m: the placement keepout of the row's kind (two objects' centres are at least
    #: the sum of their keepouts apart; :func:`placement_keepout`).
    keepout: np.ndarray
    #: ``(m,)``: the row surely holds an object (a LiDAR bin read above both neighbours, or the
    #: simulator); other rows may hold only a neighbour's alias
    #: (:func:`~semdp.embedded.lidar_bounds.bin_regions`).
    own: np.ndarray

    def where(self, mask: np.ndarray) -> Regions:
        """The rows where ``mask`` holds."""
        return Regions(*(a[mask] for a in self))

    def plus(self, other: Regions) -> Regions:
        """These rows, then ``other``'s."""
        return Regions(*(np.concatenate([a, b]) for a, b in zip(self, other, strict=True)))

    def same_objects(self, seen: Regions) -> np.ndarray:
        """``(m, n)``: whether an object row ``i`` may hold is the one ``seen``'s row ``j``
        holds (objects that do not move: static kinds, gremlins' homes). Row ``j`` must be an
        object's own (:attr:`own`: an alias row holds no object to be); a row's object lies
        within its spread of its centre, so the two objects are at most
        ``spread_i + |c_i - c_j| + spread_j`` apart, and two different objects at least
        ``keepout_i + keepout_j``: below that, they are one."""
        apart = np.hypot(self.rows[:, None, 0] - seen.rows[None, :, 0],
                         self.rows[:, None, 1] - seen.rows[None, :, 1])
        return (seen.own[None, :] & (self.spread[:, None] + apart + seen.spread[None, :]
                                     < self.keepout[:, None] + seen.keepout[None, :]))

    def unexplained_by(self, seen: Regions) -> Regions:
        """The rows that may hold an object none of ``seen``'s rows holds
        (:meth:`same_objects`)."""
        if not len(self.rows) or not len(seen.rows):
            return self
        return self.where(~self.same_objects(seen).any(axis=1))


def _read_only(*arrays: np.ndarray) -> Regions:
    """:class:`Regions` of ``arrays``, made read-only."""
    for array in arrays:
        array.flags.writeable = False
    return Regions(*arrays)


#: The one empty set of rows (read-only: every operation on it makes new arrays).
_NO_REGIONS = _read_only(np.zeros((0, 3)), np.zeros(0, dtype=bool), np.zeros(0, dtype=bool),
                         np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool))


def no_regions() -> Regions:
    """No rows."""
    return _NO_REGIONS


def placement_keepout(base: Any, kind: str) -> float:
    """The placement keepout (m) of ``kind`` in ``base``'s layout (the Safety Gym layouts'
    :class:`~sims.safety_gym.config.ObjectSpec`); 0 where the env states none."""
    spec = getattr(base, "layout_spec", None)
    objects = getattr(spec, "objects", {})
    return float(objects[kind].keepout) if kind in objects else 0.0


class CostRegions:
    """The regions part of :class:`~semdp.embedded.shield.SafetyShield`, which sets its
    attributes (one object: checkpoints pickle the filter whole).

    Attributes:
        margin: extra clearance beyond each cost region (m).
        perception: ``"lidar"`` or ``"gt"``.
        kinds: obstacle kinds filtered against.
        lidar_bearing_bound: how a lit LiDAR bin's bearing is bounded, one of
            :data:`~semdp.embedded.lidar_bounds.BEARING_BOUNDS`.
    """

    margin: float
    perception: str
    kinds: tuple[str, ...]
    lidar_bearing_bound: str
    #: Each filtered kind's cost radius (the robot's extent added to the contact kinds).
    _radii: dict[str, float]
    #: The buttons LiDAR channel's memory (:class:`~semdp.embedded.perception.ButtonMemory`),
    #: made on first use (None until then).
    _buttons: ButtonMemory | None

    @property
    def button_memory(self) -> ButtonMemory:
        """The memory of the buttons LiDAR channel (forgotten by :meth:`new_episode`)."""
        if self._buttons is None:
            self._buttons = ButtonMemory()
        return self._buttons

    def new_episode(self) -> None:
        """Forget what belongs to the last episode (the buttons' memory)."""
        self.button_memory.forget()

    @staticmethod
    def _orbit(base: Any, kind: str) -> tuple[np.ndarray, float]:
        """``(shift, extra radius)`` that turn a seen object of ``kind`` into its region's disc:
        a gremlin's ``-o(t)`` and :data:`~semdp.embedded.perception.GREMLIN_ORBIT` (its orbit
        around its home); nothing for the static kinds."""
        if kind != "gremlins":
            return np.zeros(2), 0.0
        return -gremlin_offset(episode_time(base)), GREMLIN_ORBIT

    def cost_regions(self, base: Any, obs: np.ndarray) -> np.ndarray:
        """``(m, 3)`` rows ``[x, y, R]``: the cost regions plus the margin."""
        return self._regions(base, obs).rows

    def _regions(self, base: Any, obs: np.ndarray) -> Regions:
        """:meth:`cost_regions` with what the filter knows of each row (:class:`Regions`)."""
        if self.perception == "lidar" and self.lidar_bearing_bound != "none":
            return self._bounded_lidar_regions(base, obs)
        gt = self.perception == "gt"
        spread = 0.0 if gt else math.inf  # "none": not bounded
        out = no_regions()
        for kind in self.kinds:
            if kind not in self._radii:
                continue
            found = perceive_obstacles(base, obs, self.perception, kinds=(kind,),
                                       memory=self.button_memory, gremlins="orbit")
            if len(found):
                found = np.array(found, dtype=np.float64)
                found[:, 2] = self._radii[kind] + self.margin + self._orbit(base, kind)[1]
                out = out.plus(_rows_of(base, kind, found, np.full(len(found), spread),
                                        np.full(len(found), gt)))
        return out

    def _lidar_channels(self, base: Any, obs: np.ndarray, kinds: tuple[str, ...] | None = None
                        ) -> Iterator[tuple[str, float, np.ndarray, LidarFrame]]:
        """``(kind, cost radius + margin, shift, frame)`` of each filtered kind the robot senses
        (buttons: :func:`~semdp.embedded.perception.button_frame`, possibly remembered; the
        shift and the radius of a gremlin's orbit: :meth:`_orbit`); ``kinds``: only these of
        the filtered kinds."""
        position = np.asarray(base.robot_position, dtype=np.float64)
        heading = float(base.robot_heading)
        for kind in self.kinds if kinds is None else kinds:
            key = f"{kind}_lidar"
            if kind not in self._radii or key not in base.obs_slices:
                continue
            if kind == "buttons":
                frame = button_frame(base, obs, self.button_memory)
                if frame is None:
                    continue
            else:
                frame = LidarFrame(obs[base.obs_slices[key]], position, heading)
            shift, extra = self._orbit(base, kind)
            yield kind, self._radii[kind] + self.margin + extra, shift, frame

    def _bounded_lidar_regions(self, base: Any, obs: np.ndarray) -> Regions:
        """Every lit bin of each kind's LiDAR as a region bounding its object's bearing
        (:func:`~semdp.embedded.lidar_bounds.bin_regions` under :attr:`lidar_bearing_bound`;
        the bin's allowance is the row's spread), as :meth:`_regions`."""
        out = no_regions()
        bound = self.lidar_bearing_bound
        for kind, radius, shift, frame in self._lidar_channels(base, obs):
            found = np.array(bin_regions(frame, bound), dtype=np.float64).reshape(-1, 4)
            if len(found):
                grow = found[:, 2].copy()
                found[:, :2] += shift
                found[:, 2] = radius + grow
                out = out.plus(_rows_of(base, kind, found[:, :3], grow, found[:, 3] > 0.5))
        return out

    def goal_button(self, base: Any, obs: np.ndarray) -> Regions:
        """The goal button's contact region (Button tasks; no rows elsewhere) from the goal
        LiDAR channel under :attr:`lidar_bearing_bound` (``bin`` for ``none``), or from the
        simulator with ground truth; the bins' allowances are the rows' spreads. Not a cost
        region: the plans of the moving-gremlin certificate, which model no contacts, must not
        run into it (:mod:`semdp.embedded.moving_certificate`). A task is a Button task where
        the robot has a buttons LiDAR channel; elsewhere the goal channel sees a goal area (Goal,
        Push), which is no button."""
        slices = base.obs_slices
        if ("buttons" not in self._radii or "goal_lidar" not in slices
                or "buttons_lidar" not in slices):
            return no_regions()
        radius = self._radii["buttons"] + self.margin
        if self.perception == "gt":
            x, y = (float(v) for v in base.goal_position[:2])
            return _rows_of(base, "buttons", np.array([[x, y, radius]]), np.zeros(1),
                            np.ones(1, dtype=bool))
        frame = LidarFrame(obs[base.obs_slices["goal_lidar"]],
                           np.asarray(base.robot_position, dtype=np.float64),
                           float(base.robot_heading))
        bound = "bin" if self.lidar_bearing_bound == "none" else self.lidar_bearing_bound
        found = np.array(bin_regions(frame, bound), dtype=np.float64).reshape(-1, 4)
        grow = found[:, 2].copy()
        found[:, 2] = radius + grow
        return _rows_of(base, "buttons", found[:, :3], grow, found[:, 3] > 0.5)

    def _lidar_lower_bound(self, base: Any, obs: np.ndarray) -> float:
        """A lower bound of every LiDAR region's ``distance - R`` from the nearest lit bin of
        each kind (exact ranges; the bearing allowance grows with range, hence the factor; a
        gremlin's orbit centre is its shift away); ``-inf`` when a frame was read from
        elsewhere (remembered).

        Called before every low-level step: the static kinds read their channel directly
        (their frame is the current one and their shift zero); buttons and gremlins go through
        :meth:`_lidar_channels` (the buttons' memory, the orbit)."""
        bound = math.inf
        bounded = self.lidar_bearing_bound != "none"
        shrink = 1.0 - BEARING_ERROR_PER_METRE if bounded else 1.0
        slack = RANGE_TOLERANCE if self.lidar_bearing_bound == "aliasing" else 0.0
        slices = base.obs_slices
        moving = []
        for kind in self.kinds:
            key = _LIDAR_KEYS[kind]
            if kind not in self._radii or key not in slices:
                continue
            if kind in _FRAMED_KINDS:
                moving.append(kind)
                continue
            reading = float(obs[slices[key]].max())
            if reading > 0.0:
                bound = min(bound, shrink * (1.0 - reading) * LIDAR_RANGE
                            - (self._radii[kind] + self.margin) - slack)
        if not moving:
            return bound
        position = np.asarray(base.robot_position, dtype=np.float64)
        for _, radius, shift, frame in self._lidar_channels(base, obs, tuple(moving)):
            reading = float(frame.readings.max())
            if reading <= 0.0:
                continue
            if not np.array_equal(frame.position, position):
                return -math.inf
            bound = min(bound, shrink * (1.0 - reading) * LIDAR_RANGE - radius
                        - float(np.linalg.norm(shift)) - slack)
        return bound


def _rows_of(base: Any, kind: str, rows: np.ndarray, spread: np.ndarray, own: np.ndarray
             ) -> Regions:
    """``rows`` ``(m, 3)`` of objects of ``kind`` with their ``spread`` and :attr:`own` flags
    as :class:`Regions`."""
    m = len(rows)
    return Regions(rows, np.full(m, kind in CONTACT_KINDS), np.full(m, kind == "gremlins"),
                   np.asarray(spread, dtype=np.float64),
                   np.full(m, placement_keepout(base, kind)), np.asarray(own, dtype=bool))
