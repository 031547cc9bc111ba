"""A last-line safety filter on the follower's low-level action (beyond the thesis, §3.5.2).

The thesis' planner certifies the *plan*; the robot that follows it can still leave it: its
tracking error, its momentum at the end of a window, a box pushing back. Competent high-level
policies find those gaps (they push boxes past hazards at speed). This filter closes them with
the robot's own calibrated model (:mod:`semdp.embedded.robot_models`): before every low-level
step it simulates the proposed action for one step followed by the robot's braking manoeuvre
and keeps the action only if that whole trajectory stays out of every obstacle's cost region
(plus ``margin``). Otherwise it brakes, if braking is itself certified, and else takes the
escape action that keeps the largest clearance. By induction the robot can always stop before
a cost region it can see, whatever the subgoals (a model-predictive safety filter with a
braking backup).

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

Contacts (the box, a pillar) are outside the model too: a push can leave the robot in a state
from which braking is no longer certified. ``fallback`` says what happens then: ``"escape"``
(the default) takes whichever of braking and the escape actions keeps the largest clearance
one step ahead, among those that enter no region the robot is outside of now if there are any;
``"brake"`` keeps braking. In the one training episode with cost of the
long-trained Point runs (outputs/reference/archive/semdp_converged/COMMAND.md) a push left braking
uncertified against the LiDAR-bounded regions though not against the true hazard, and the
escape choice accelerated the robot into the hazard; replayed with ``"brake"`` the episode has
no cost. Over the safety table both have no episode with cost, and ``"brake"`` replaces
1.1-5.8x more commands where the filter acts on at least 1 % of them (the Point and the Car;
outputs/reference/safety/COMMAND.md), so the default stays ``"escape"``.

**Inside a contact region** (the Button tasks' grace period: the robot starts it touching the
button it just pressed, which is a wrong button once the goal moves; a push that left it near a
pillar) one step then braking barely moves a robot at rest, so the escape cannot tell a way out
from a turn on the spot. There the escape holds each option for :data:`EXIT_STEPS` steps and
takes the one that gets farthest out of the static regions it is in (a button, not a gremlin's
orbit disc, which it may be deep inside), then out of all, with gaps measured from the robot's
outline at its predicted heading rather than from a disc of its extent, among the options that
enter no other region by more than the margin, else those that enter least
(:meth:`SafetyShield._exit`, with the trained runs' episodes that led to each part): with
goal-seeking subgoals the Point's nose, swinging back into the button as the robot turned away,
touched it after the grace period in 1 of 60 episodes on Button1 before the hold and the
outline.

A :attr:`SafetyShield.recorder`, when set, is given a :class:`FilterRecord` of every
:meth:`SafetyShield.filter` call (the robot state it read, the proposed and applied actions,
the branch taken); :mod:`semdp.evaluation.cost_trace` records the steps before a cost step with
it. None (the default) records nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.embedded.brake_kernel import compiles, kernel_for
from semdp.embedded.lidar_bounds import (
    BEARING_BOUNDS,
    BEARING_ERROR_PER_METRE,
    LIDAR_RANGE,
    RANGE_TOLERANCE,
    RECORDED_BOUNDS,
    bin_regions,
)
from semdp.embedded.perception import (
    GREMLIN_ORBIT,
    OBSTACLE_KINDS,
    PERCEPTION_MODES,
    ButtonMemory,
    LidarFrame,
    button_frame,
    episode_time,
    gremlin_offset,
    perceive_obstacles,
)
from semdp.embedded.robot_models import RobotModel, RobotState, robot_model
from semdp.embedded.shield_records import FilterRecord, ShieldStats, branch_of

#: What the filter does when neither the action nor braking is certified.
FALLBACKS = ("escape", "brake")

#: How the certificate is evaluated: ``"compiled"`` (:mod:`semdp.embedded.brake_kernel`, the
#: same numbers), ``"native"`` (the same function as C compiled once per machine,
#: :mod:`solvers.native`; the same numbers again) or ``"python"`` (the plain path).
KERNELS = ("compiled", "native", "python")

#: Steps an escape from inside a region is held in :meth:`SafetyShield._exit`'s rollouts: the
#: Button task's grace period after a press (``BUTTON_RESAMPLING_DELAY``), within which the robot
#: must be off the button it pressed.
EXIT_STEPS = 10

#: Kinds whose cost is a contact with the robot's outline: their regions add the robot's extent.
_CONTACT_KINDS = ("vases", "pillars", "gremlins", "buttons")
#: Kinds whose LiDAR frame is more than the current channel: the buttons' (remembered while
#: blank, less the goal button) and the gremlins' (shifted to the orbit's centre).
_FRAMED_KINDS = ("buttons", "gremlins")
#: Each kind's LiDAR observation key.
_LIDAR_KEYS = {kind: f"{kind}_lidar" for kind in OBSTACLE_KINDS}

class SafetyShield:
    """Model-predictive braking filter on the low-level action (see the module docstring).

    Args:
        margin: extra clearance beyond each cost region (m).
        perception: ``"lidar"`` (the robot's own sensor, as the planner) or ``"gt"``;
            ``"lidar_refined"`` (a planner's mode) is read as ``"lidar"``: the filter bounds
            every lit bin by its own bearing error, refined or not.
        kinds: obstacle kinds filtered against.
        lidar_bearing_bound: LiDAR only, how a lit bin's bearing is bounded
            (:data:`~semdp.embedded.lidar_bounds.BEARING_BOUNDS`): ``"aliasing"`` (the neighbours'
            readings bound it), ``"bin"`` (the whole bin), ``"none"`` (the planner's peak
            reconstruction as it is); ``True`` / ``False`` (configs recorded before the
            aliasing bound) are ``"bin"`` / ``"none"``.
        fallback: when neither the action nor braking is certified: ``"escape"`` (the best
            one-step clearance among braking and the escape actions) or ``"brake"``.
        kernel: how :meth:`clearance` is evaluated (:data:`KERNELS`): ``"compiled"`` (the
            default: the braking manoeuvre as one CasADi function,
            :mod:`semdp.embedded.brake_kernel`, equal to the plain path bit for bit),
            ``"native"`` (that function as compiled C, equal too) or ``"python"`` (the plain
            path, the reference).
    """

    #: Class-level default: filters pickled before ``fallback`` existed (checkpoints hold the
    #: env) resume with the behaviour they had.
    fallback: str = "escape"
    #: Class-level default: filters pickled before ``kernel`` existed take the compiled one
    #: (the same numbers).
    kernel: str = "compiled"
    #: Given a :class:`FilterRecord` after every :meth:`filter` call when set (diagnostics:
    #: :mod:`semdp.evaluation.cost_trace`); None records nothing. Class-level, so that filters
    #: unpickled from a checkpoint have it too.
    recorder: Callable[[FilterRecord], None] | None = None
    #: The buttons LiDAR channel's memory (:class:`~semdp.embedded.perception.ButtonMemory`),
    #: made on first use; class-level so that filters pickled before it existed have it.
    _buttons: ButtonMemory | None = None

    def __init__(self, margin: float = 0.05, perception: str = "lidar",
                 kinds: tuple[str, ...] | list[str] = OBSTACLE_KINDS,
                 lidar_bearing_bound: str | bool = "aliasing", fallback: str = "escape",
                 kernel: str = "compiled") -> None:
        if not margin >= 0:
            raise ValueError(f"shield margin must be >= 0, got {margin}")
        if perception not in PERCEPTION_MODES:
            raise ValueError(
                f"shield perception must be one of {PERCEPTION_MODES}, got {perception!r}")
        if fallback not in FALLBACKS:
            raise ValueError(f"shield fallback must be one of {FALLBACKS}, got {fallback!r}")
        if kernel not in KERNELS:
            raise ValueError(f"shield kernel must be one of {KERNELS}, got {kernel!r}")
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad:
            raise ValueError(f"unknown obstacle kinds {bad}; valid: {list(OBSTACLE_KINDS)}")
        bound = RECORDED_BOUNDS.get(lidar_bearing_bound, lidar_bearing_bound)  # type: ignore[call-overload]
        if bound not in BEARING_BOUNDS:
            raise ValueError(f"shield lidar_bearing_bound must be one of {BEARING_BOUNDS}, "
                             f"got {lidar_bearing_bound!r}")
        self.margin = float(margin)
        self.perception = "lidar" if perception == "lidar_refined" else perception
        self.kinds = tuple(kinds)
        self.lidar_bearing_bound = bound
        self.fallback = fallback
        self.kernel = kernel
        self.stats = ShieldStats()
        self._model: RobotModel | None = None
        self._radii: dict[str, float] = {}

    def bind(self, base: Any) -> None:
        """Attach to the unwrapped env: its robot's model and each kind's cost radius."""
        self._model = robot_model(base.robot_name)
        sizes = {kind: float(rows[0, 2]) for kind, rows in base.obstacles_by_type().items()
                 if len(rows)}
        for kind in self.kinds:
            size = sizes.get(kind, 0.0)
            self._radii[kind] = size + (self._model.extent if kind in _CONTACT_KINDS else 0.0)

    @property
    def bearing_bound(self) -> str:
        """:attr:`lidar_bearing_bound` as one of :data:`BEARING_BOUNDS` (filters pickled before
        the aliasing bound hold ``True`` / ``False``)."""
        return RECORDED_BOUNDS.get(self.lidar_bearing_bound, self.lidar_bearing_bound)

    def reset_stats(self) -> None:
        """Zero the counters."""
        self.stats = ShieldStats()

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
        return self._regions(base, obs)[0]

    def _regions(self, base: Any, obs: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`cost_regions` and, per row, whether its cost is a contact with the robot's
        outline (its ``R`` then holds the robot's extent) and whether it is a gremlin's orbit
        disc (a moving object's: inside it the gremlin may come, elsewhere on its orbit)."""
        if self.perception == "lidar" and self.bearing_bound != "none":
            return self._bounded_lidar_regions(base, obs)
        rows, contact, orbit = [], [], []
        for kind in self.kinds:
            if kind not in self._radii:
                continue
            found = perceive_obstacles(base, obs, self.perception, kinds=(kind,),
                                       memory=self.button_memory)  # gremlins: orbit discs
            if len(found):
                found = np.array(found, dtype=np.float64)
                found[:, 2] = self._radii[kind] + self.margin + self._orbit(base, kind)[1]
                rows.append(found)
                contact.append(np.full(len(found), kind in _CONTACT_KINDS))
                orbit.append(np.full(len(found), kind == "gremlins"))
        return _stack(rows, contact, orbit)

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

    def _bounded_lidar_regions(self, base: Any, obs: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every lit bin of each kind's LiDAR as a region bounding its object's bearing
        (:func:`~semdp.embedded.lidar_bounds.bin_regions` under :attr:`bearing_bound`), and the
        flags of :meth:`_regions`."""
        rows: list[tuple[float, float, float]] = []
        contact: list[bool] = []
        orbit: list[bool] = []
        bound = self.bearing_bound
        for kind, radius, shift, frame in self._lidar_channels(base, obs):
            sx, sy = float(shift[0]), float(shift[1])
            found = bin_regions(frame, bound)
            rows += [(x + sx, y + sy, radius + grow) for x, y, grow in found]
            contact += [kind in _CONTACT_KINDS] * len(found)
            orbit += [kind == "gremlins"] * len(found)
        if not rows:
            return np.zeros((0, 3)), np.zeros(0, dtype=bool), np.zeros(0, dtype=bool)
        return (np.array(rows, dtype=np.float64), np.array(contact, dtype=bool),
                np.array(orbit, dtype=bool))

    def _lidar_lower_bound(self, base: Any, obs: np.ndarray) -> float:
        """A lower bound of every LiDAR region's ``distance - R`` from the nearest lit bin of
        each kind (exact ranges; the bearing allowance grows with range, hence the factor; a
        gremlin's orbit centre is its shift away); ``-inf`` when a frame was read from
        elsewhere (remembered).

        Called before every low-level step: the static kinds read their channel directly
        (their frame is the current one and their shift zero); buttons and gremlins go through
        :meth:`_lidar_channels` (the buttons' memory, the orbit)."""
        bound = math.inf
        bounded = self.bearing_bound != "none"
        shrink = 1.0 - BEARING_ERROR_PER_METRE if bounded else 1.0
        slack = RANGE_TOLERANCE if self.bearing_bound == "aliasing" else 0.0
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

    def clearance(self, state: RobotState, first: np.ndarray, regions: np.ndarray) -> float:
        """Smallest ``distance - R`` to ``regions`` over ``first`` then the braking manoeuvre,
        by the bound robot's model: the filter's certificate (>= 0: certified). ``regions``:
        rows ``[x, y, R]``."""
        if self._model is None:
            raise RuntimeError("bind() the filter to an env first")
        return self._clearance(self._model, state, first, regions)

    def _clearance(self, model: RobotModel, state: RobotState, first: np.ndarray,
                   regions: np.ndarray) -> float:
        """Smallest ``distance - R`` over ``first`` then the braking manoeuvre."""
        s = model.step(state, first)
        if self.kernel != "python" and compiles(model):
            return kernel_for(model, self.kernel == "native")(s, regions)
        points = np.empty((model.horizon + 1, 2))
        points[0] = (s.x, s.y)
        points[1:] = model.brake_path(s)
        gaps = np.linalg.norm(points[:, None, :] - regions[None, :, :2], axis=-1)
        return float((gaps - regions[None, :, 2]).min())

    def filter(self, action: np.ndarray, base: Any, obs: np.ndarray) -> np.ndarray:
        """The action to apply: ``action`` if certified, else braking, else the best escape.

        A set :attr:`recorder` is then given the call's :class:`FilterRecord`.
        """
        if self.recorder is None:
            return self._filter(action, base, obs)
        before = (self.stats.checked, self.stats.braked, self.stats.escaped)
        body = base.body
        state = RobotState(body.position.x, body.position.y, body.velocity.x, body.velocity.y,
                           body.angle, body.angular_velocity)
        applied = self._filter(action, base, obs)
        assert self._model is not None
        self.recorder(FilterRecord(self, self._model, base, obs, state, np.asarray(action),
                                   np.asarray(applied), branch_of(before, self.stats)))
        return applied

    def _filter(self, action: np.ndarray, base: Any, obs: np.ndarray) -> np.ndarray:
        """:meth:`filter`'s decision."""
        if self._model is None:
            self.bind(base)
        model = self._model
        assert model is not None
        self.stats.steps += 1
        body = base.body
        (x, y), (vx, vy) = body.position, body.velocity
        state = RobotState(x, y, vx, vy, body.angle, body.angular_velocity)
        reach = model.stopping_reach(state) + 0.1
        if self.perception == "lidar" and self._lidar_lower_bound(base, obs) >= reach:
            return action  # nothing any lit bin could hold is within reach: no reconstruction
        regions, contact, orbit = self._regions(base, obs)
        if not len(regions):
            return action
        near = np.linalg.norm(regions[:, :2] - (state.x, state.y), axis=1) - regions[:, 2] < reach
        regions, contact, orbit = regions[near], contact[near], orbit[near]
        if not len(regions):
            return action
        self.stats.checked += 1
        if self._clearance(model, state, action, regions) >= 0.0:
            return action
        brake = model.backup(state)
        if self.fallback == "brake" or self._clearance(model, state, brake, regions) >= 0.0:
            self.stats.braked += 1
            return brake.astype(np.asarray(action).dtype)
        self.stats.escaped += 1
        options = [brake, *model.escapes]
        return np.asarray(options[self._escape(model, state, options, regions, contact, orbit)],
                          dtype=np.asarray(action).dtype)

    def _escape(self, model: RobotModel, state: RobotState, options: list[np.ndarray],
                regions: np.ndarray, contact: np.ndarray, orbit: np.ndarray) -> int:
        """The option whose step then braking keeps the largest clearance from ``regions``,
        among those that enter no region the robot is outside of now if there are any: getting
        out of one region (an orbit disc it finds itself in, a LiDAR region that lit around it)
        must not take the robot into another (a hazard)."""
        scores = [self._clearance(model, state, a, regions) for a in options]
        best = int(np.argmax(scores))
        outside = np.linalg.norm(regions[:, :2] - (state.x, state.y), axis=1) >= regions[:, 2]
        if scores[best] < 0.0 and (contact & ~outside).any():
            return self._exit(model, state, options, regions, contact, orbit, outside)
        if scores[best] >= 0.0 or not outside.any() or outside.all():
            return best
        kept = [i for i, a in enumerate(options)
                if self._clearance(model, state, a, regions[outside]) >= 0.0]
        return max(kept, key=scores.__getitem__) if kept and best not in kept else best

    def _exit(self, model: RobotModel, state: RobotState, options: list[np.ndarray],
              regions: np.ndarray, contact: np.ndarray, orbit: np.ndarray,
              outside: np.ndarray) -> int:
        """Inside a region (a button just pressed, an orbit disc, a LiDAR region lit around the
        robot): the option that, held for :data:`EXIT_STEPS` steps, gets farthest out of the
        static regions it is in (every kind but a gremlin's orbit disc), then farthest out of
        all the regions it is in, at the best step of its hold; among the options whose hold
        enters no region the robot is outside of (by more than :attr:`margin` when it is that
        deep in a static region) if there are any, else among those that enter least.

        * Static regions first: a static region the robot is in is a cost at hand (a button
          whose grace period is running out); an orbit disc it is in is a cost only if the
          gremlin comes round. Ranked together, a disc the robot was deep inside chose: on a
          trained MassButton1 run the escapes alternated between opposite directions on a
          just-pressed button until its grace period ended.
        * Entries up to the margin when the robot is deeper than the margin in a static region
          (touching a button it pressed, by its perception): the margin is clearance beyond
          the object's cost radius, so entering another region by less does not reach that
          object. Without it a Point that had pressed a button 0.58 m from another could leave
          neither (the way out of the one entered the other's region by 2 cm) and stayed until
          the grace period ended. Only then: allowed always, a Point inside a hazard's region
          (not the hazard) crept into a wrong button's, and wedged between the two, slid into
          the hazard.
        * The least entry when every option enters: a Point escaping an orbit disc with
          momentum towards a hazard, every option's hold entering the hazard's region, was
          otherwise ranked by the disc alone and slid into the hazard.

        A contact region's gap is measured from the robot's outline at its predicted heading
        (:class:`~semdp.embedded.robot_models.Outline`), not from a disc of its extent: a robot
        at rest moves a few centimetres in the grace period after a press, and whether it
        touches the button again depends on where its nose (the Point) or its wheels (the Car)
        swing, which a disc cannot tell."""
        poses = np.empty((len(options), EXIT_STEPS, 3))
        for i, a in enumerate(options):
            s = state
            for t in range(EXIT_STEPS):
                s = model.step(s, a)
                poses[i, t] = (s.x, s.y, s.yaw)
        flat = poses.reshape(-1, 3)
        gaps = np.linalg.norm(flat[:, None, :2] - regions[None, :, :2], axis=-1) - regions[:, 2]
        exiting = contact & ~outside
        if exiting.any():  # R without the robot's extent, from the outline
            gaps[:, exiting] = model.outline.distance(
                flat[:, 0], flat[:, 1], flat[:, 2], regions[exiting, :2]) - (
                regions[exiting, 2] - model.extent)
        gaps = gaps.reshape(len(options), EXIT_STEPS, -1)
        depth = gaps[:, :, ~outside].min(axis=2).max(axis=1)
        static = ~outside & ~orbit
        static_depth = (gaps[:, :, static].min(axis=2).max(axis=1) if static.any()
                        else np.zeros(len(options)))
        entries = (gaps[:, :, outside].min(axis=(1, 2)) if outside.any()
                   else np.zeros(len(options)))
        tolerance = self.margin if self._static_depth_now(model, state, regions, contact,
                                                          static) < -self.margin else 0.0
        kept = [i for i in range(len(options)) if entries[i] >= -tolerance]
        if not kept:
            kept = [i for i in range(len(options)) if entries[i] == entries.max()]
        return max(kept, key=lambda i: (static_depth[i], depth[i]))

    @staticmethod
    def _static_depth_now(model: RobotModel, state: RobotState, regions: np.ndarray,
                          contact: np.ndarray, static: np.ndarray) -> float:
        """The robot's gap out of the static regions it is in, where it is now (contact
        regions from its outline, as in :meth:`_exit`); ``inf`` if it is in none."""
        if not static.any():
            return math.inf
        rows = regions[static]
        gaps = np.hypot(rows[:, 0] - state.x, rows[:, 1] - state.y) - rows[:, 2]
        touching = contact[static]
        if touching.any():
            gaps[touching] = model.outline.distance(state.x, state.y, state.yaw,
                                                    rows[touching, :2]) - (
                rows[touching, 2] - model.extent)
        return float(gaps.min())


class ShieldedEnv(gym.Wrapper):
    """Applies a :class:`SafetyShield` to every action of a Safety Gym replica env.

    The Safety-Embedded MDP wraps this (``SafetyEmbeddedEnv(..., shield=...)``), so the
    follower's every low-level command passes the filter; ``info["shield_replaced"]`` says
    whether this step's command was replaced.
    """

    def __init__(self, env: gym.Env, shield: SafetyShield) -> None:
        super().__init__(env)
        self.shield = shield
        self._obs: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset and bind the filter to the new episode's objects."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.shield.bind(self.env.unwrapped)
        self.shield.new_episode()
        self._obs = obs
        return obs, info

    def step(self, action):
        """Filter ``action``, then step."""
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        safe = self.shield.filter(np.asarray(action), self.env.unwrapped, self._obs)
        obs, reward, terminated, truncated, info = self.env.step(safe)
        self._obs = obs
        info["shield_replaced"] = safe is not action and not np.array_equal(safe, action)
        return obs, reward, terminated, truncated, info


def _stack(rows: list[np.ndarray], contact: list[np.ndarray], orbit: list[np.ndarray]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Region rows ``(m, 3)`` and their contact and orbit flags ``(m,)`` from per-kind lists."""
    if not rows:
        return np.zeros((0, 3)), np.zeros(0, dtype=bool), np.zeros(0, dtype=bool)
    return np.concatenate(rows), np.concatenate(contact), np.concatenate(orbit)
