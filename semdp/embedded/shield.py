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

The cost regions are discs around the obstacles the planner sees, by kind, read from the LiDAR
or the simulator (:mod:`semdp.embedded.cost_regions`); inside one, the escape holds each option
for a few steps (:mod:`semdp.embedded.exit_planning`).

Contacts (the box, a pillar) are outside the model: a push can leave the robot in a state
from which braking is no longer certified. ``fallback`` says what happens then: ``"escape"``
(the default) takes whichever of braking and the escape actions keeps the largest clearance
one step ahead, among those that enter no region the robot is outside of now if there are any;
``"brake"`` keeps braking. In the one training episode with cost of the long-trained Point runs
(outputs/reference/archive/semdp_converged/COMMAND.md) a push left braking uncertified against
the LiDAR-bounded regions though not against the true hazard, and the escape choice accelerated
the robot into the hazard; replayed with ``"brake"`` the episode has no cost. Over the safety
table both have no episode with cost, and ``"brake"`` replaces 1.1-5.8x more commands where the
filter acts on 1 % or more (outputs/reference/safety/COMMAND.md): the default stays ``"escape"``.

A :attr:`SafetyShield.recorder`, when set, is given a :class:`FilterRecord` of every
:meth:`SafetyShield.filter` call (the robot state it read, the proposed and applied actions,
the branch taken); :mod:`semdp.evaluation.cost_trace` records the steps before a cost step with
it. None (the default) records nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from semdp.embedded.brake_kernel import compiles, kernel_for
from semdp.embedded.cost_regions import CONTACT_KINDS, CostRegions, Regions, no_regions
from semdp.embedded.exit_planning import EXIT_STEPS, exit_option, presses_without_exit
from semdp.embedded.lidar_bounds import BEARING_BOUNDS
from semdp.embedded.moving_certificate import (
    Gremlins,
    KeptFrame,
    Plan,
    certified_plans,
    choose,
    clearances,
    plan_points,
    plans_for,
)
from semdp.embedded.perception import (
    GREMLIN_MODELS,
    OBSTACLE_KINDS,
    PERCEPTION_MODES,
    episode_time,
)
from semdp.embedded.robot_models import RobotModel, RobotState, robot_model
from semdp.embedded.shield_records import FilterRecord, ShieldStats, branch_of
from solvers.planner.geometry import point_distances

#: What the filter does when neither the action nor braking is certified.
FALLBACKS = ("escape", "brake")

#: How the certificate is evaluated: ``"compiled"`` (:mod:`semdp.embedded.brake_kernel`, the
#: same numbers), ``"native"`` (the same function as C compiled once per machine,
#: :mod:`solvers.native`; the same numbers again) or ``"python"`` (the plain path).
KERNELS = ("compiled", "native", "python")


class SafetyShield(CostRegions):
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
            reconstruction as it is).
        fallback: when neither the action nor braking is certified: ``"escape"`` (the best
            one-step clearance among braking and the escape actions) or ``"brake"``.
        kernel: how :meth:`clearance` is evaluated (:data:`KERNELS`): ``"native"`` (the
            default: the braking manoeuvre as one CasADi function,
            :mod:`semdp.embedded.brake_kernel`, compiled to C, equal to the plain path bit for
            bit), ``"compiled"`` (that function in CasADi's virtual machine, equal too) or
            ``"python"`` (the plain path, the reference); the same choice for the plan
            rollouts of the exit and the moving certificate
            (:mod:`semdp.embedded.plan_rollouts`).
        gremlins: :data:`~semdp.embedded.perception.GREMLIN_MODELS`: ``"moving"`` (the
            default: a gremlin's orbit disc may be crossed under a plan certified against the
            gremlin's position at each step, :mod:`semdp.embedded.moving_certificate`) or
            ``"orbit"`` (the whole disc is a static region).
    """

    #: Given a :class:`FilterRecord` after every :meth:`filter` call when set (diagnostics:
    #: :mod:`semdp.evaluation.cost_trace`); None records nothing. Class-level, so that filters
    #: unpickled from a checkpoint have it too.
    recorder: Callable[[FilterRecord], None] | None = None

    def __init__(self, margin: float = 0.05, perception: str = "lidar",
                 kinds: tuple[str, ...] | list[str] = OBSTACLE_KINDS,
                 lidar_bearing_bound: str = "aliasing", fallback: str = "escape",
                 kernel: str = "native", gremlins: str = "moving") -> None:
        if not margin >= 0:
            raise ValueError(f"shield margin must be >= 0, got {margin}")
        if perception not in PERCEPTION_MODES:
            raise ValueError(
                f"shield perception must be one of {PERCEPTION_MODES}, got {perception!r}")
        if fallback not in FALLBACKS:
            raise ValueError(f"shield fallback must be one of {FALLBACKS}, got {fallback!r}")
        if kernel not in KERNELS:
            raise ValueError(f"shield kernel must be one of {KERNELS}, got {kernel!r}")
        if gremlins not in GREMLIN_MODELS:
            raise ValueError(
                f"shield gremlins must be one of {GREMLIN_MODELS}, got {gremlins!r}")
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad:
            raise ValueError(f"unknown obstacle kinds {bad}; valid: {list(OBSTACLE_KINDS)}")
        if lidar_bearing_bound not in BEARING_BOUNDS:
            raise ValueError(f"shield lidar_bearing_bound must be one of {BEARING_BOUNDS}, "
                             f"got {lidar_bearing_bound!r}")
        self.margin = float(margin)
        self.perception = "lidar" if perception == "lidar_refined" else perception
        self.kinds = tuple(kinds)
        self.lidar_bearing_bound = lidar_bearing_bound
        self.fallback = fallback
        self.kernel = kernel
        self.gremlins = gremlins
        self._plan: Plan | None = None
        #: The static rows and gremlin homes the kept plan was certified against.
        self._plan_seen: KeptFrame | None = None
        self._kept_for = 0  # steps the best-effort plan has been kept (_best_effort)
        self.stats = ShieldStats()
        self._model: RobotModel | None = None
        self._radii: dict[str, float] = {}
        self._buttons = None

    def bind(self, base: Any) -> None:
        """Attach to the unwrapped env: its robot's model and each kind's cost radius."""
        self._model = robot_model(base.robot_name)
        sizes = {kind: float(rows[0, 2]) for kind, rows in base.obstacles_by_type().items()
                 if len(rows)}
        for kind in self.kinds:
            size = sizes.get(kind, 0.0)
            self._radii[kind] = size + (self._model.extent if kind in CONTACT_KINDS else 0.0)

    def new_episode(self) -> None:
        """Forget the last episode's buttons and the moving-gremlin plan kept."""
        super().new_episode()
        self._plan, self._plan_seen, self._kept_for = None, None, 0

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
        gaps = point_distances(points, regions[:, :2])
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
        goal_button = self.goal_button(base, obs) if self.gremlins == "moving" else None
        goal = self._goal_within(state, goal_button, reach)
        if (self.perception == "lidar" and not len(goal.rows)
                and self._lidar_lower_bound(base, obs) >= reach):
            return action  # nothing any lit bin could hold is within reach: no reconstruction
        seen = self._regions(base, obs)
        refused = presses_without_exit(model, state, goal.rows, seen.rows[seen.orbit],
                                       self.margin, self.kernel)
        if refused.any():  # the goal button is a cost region where a press has no way out
            seen = seen.plus(goal.where(refused))
        every, every_contact, every_orbit = seen.rows, seen.contact, seen.orbit
        if not len(every):
            return action
        near = _distances(state, every) - every[:, 2] < reach
        regions, contact, orbit = every[near], every_contact[near], every_orbit[near]
        if not len(regions):
            return action
        self.stats.checked += 1
        if self._clearance(model, state, action, regions) >= 0.0:
            return action
        if self.gremlins == "moving" and orbit.any():
            assert goal_button is not None
            moved = self._moving(model, state, action, base, seen, goal_button)
            if moved is action:
                return action  # kept: the same object, so that callers count no intervention
            if moved is not None:
                return moved.astype(np.asarray(action).dtype)
        brake = model.backup(state)
        if self.fallback == "brake" or self._clearance(model, state, brake, regions) >= 0.0:
            self.stats.braked += 1
            return brake.astype(np.asarray(action).dtype)
        self.stats.escaped += 1
        options = [brake, *model.escapes]
        return np.asarray(options[self._escape(model, state, options, regions, contact, orbit)],
                          dtype=np.asarray(action).dtype)

    @staticmethod
    def _goal_within(state: RobotState, goal_button: Regions | None, reach: float) -> Regions:
        """Under the moving certificate, the goal button's contact regions within ``reach`` of
        the robot (a press it might make now; refused by
        :func:`~semdp.embedded.exit_planning.presses_without_exit` where the way out of the
        pressed button has to cross an orbit disc); none otherwise (``goal_button`` None)."""
        if goal_button is None or not len(goal_button.rows):
            return no_regions()
        rows = goal_button.rows
        return goal_button.where(_distances(state, rows) - rows[:, 2] < reach)

    def _moving(self, model: RobotModel, state: RobotState, action: np.ndarray, base: Any,
                seen: Regions, goal_button: Regions) -> np.ndarray | None:
        """``action`` if it is certified as the first step of a plan against the gremlins'
        positions, else the first action of a plan certified from here, else None
        (:mod:`semdp.embedded.moving_certificate`). The plan kept from the last step is tried
        alone first, each time: one rollout instead of the whole set.

        Deeper than the margin in a static region (the button just pressed, once the goal
        moved; :meth:`_inside_static`) no plan is certified and every plan scores the same
        depth at its first step: None, so that the exit of
        :mod:`semdp.embedded.exit_planning` takes the robot out (best-effort plans
        ranked by that depth alternated between ways out until the grace period ended)."""
        if self._inside_static(state, seen.where(~seen.orbit)):
            self._plan = None
            return None
        homes = seen.where(seen.orbit)
        gremlins = Gremlins(homes.rows, episode_time(base), model.h * model.substeps)
        statics = seen.where(~seen.orbit).plus(goal_button)
        static = statics.rows
        kept = self._plan
        first = np.asarray(action, dtype=np.float64)
        for start in (first, None):
            plan = None
            frame = None if kept is None else self._kept_frame(model, state, start, kept,
                                                               statics, homes, gremlins)
            if frame is not None:
                plan = kept
            else:
                plans = plans_for(model)
                scores = certified_plans(model, state, start, plans, static, gremlins,
                                         self.margin, self.kernel)
                plan = choose(plans, scores)
                frame = KeptFrame(statics, homes, (state.x, state.y), gremlins.time)
            if plan is not None:
                self._plan_seen = frame
            if plan is not None and start is not None:
                self._plan = plan
                return action
            if plan is not None:
                self.stats.braked += 1
                break
        else:  # no plan certified from here either
            if not (_distances(state, gremlins.homes) < gremlins.homes[:, 2]).any():
                self._plan = None
                return None  # outside every disc: the static rules' braking and escapes
            self.stats.escaped += 1  # inside an orbit disc: the plan that keeps most clearance
            plan = self._best_effort(model, state, plans, scores, kept, static, gremlins)
            self._plan_seen = None  # not certified: nothing to keep it against
        self._plan = plan.shorter()
        return np.array(plan.action) if plan.hold else model.backup(state)

    def _inside_static(self, state: RobotState, static: Regions) -> bool:
        """Whether the robot may be touching a static object: deeper than the margin in one
        of today's rows (the margin is no part of the object's region; within it the plans'
        depth floor, :func:`~semdp.embedded.moving_certificate.clearances`, keeps them out of
        the object), unless a row the kept plan was certified against surely holds an object
        (:attr:`~semdp.embedded.cost_regions.Regions.own`), the one today's row may hold
        (:meth:`~semdp.embedded.cost_regions.Regions.same_objects`), and the robot is no
        deeper than the margin in it (the object's region lies in it). A Car that drifted
        0.01 m into a button's margin, and one that a button's LiDAR region widened around
        0.033 m outside the button, gave up their kept plans inside orbit discs and were hit;
        an alias row (no object) next to a button a Mass had just pressed must not clear the
        button's own row."""
        inside = _distances(state, static.rows) < static.rows[:, 2] - self.margin
        if (not inside.any() or self._plan_seen is None
                or not len(self._plan_seen.statics.rows)):
            return bool(inside.any())
        kept = self._plan_seen.statics
        outside = _distances(state, kept.rows) >= kept.rows[:, 2] - self.margin
        cleared = (static.where(inside).same_objects(kept) & outside[None, :]).any(axis=1)
        return not cleared.all()

    def _best_effort(self, model: RobotModel, state: RobotState, plans: list[Plan],
                     scores: np.ndarray, kept: Plan | None, static: np.ndarray,
                     gremlins: Gremlins) -> Plan:
        """Inside an orbit disc with no plan certified: the plan with the largest clearance,
        except that the best-effort plan of the last step, one step shorter, is kept unless
        another one clears more by the filter's margin, for at most
        :data:`~semdp.embedded.exit_planning.EXIT_STEPS` steps. Chosen afresh at every step, the
        best plan alternated between driving on and reversing as the LiDAR's candidates came
        and went, and a Point rocked in place until the gremlin came round; kept for as long as
        it lasted (up to 50 steps), a Car turned in place inside the disc until it was hit."""
        best = int(np.argmax(scores))
        if (kept is not None and kept.hold > 0 and self._plan_seen is None
                and self._kept_for < EXIT_STEPS):
            own = certified_plans(model, state, None, [kept], static, gremlins, self.margin,
                                  self.kernel)[0]
            if own >= scores[best] - self.margin:
                self._kept_for += 1
                return kept
        self._kept_for = 0
        return plans[best]

    def _kept_frame(self, model: RobotModel, state: RobotState, start: np.ndarray | None,
                    kept: Plan, statics: Regions, homes: Regions, gremlins: Gremlins
                    ) -> KeptFrame | None:
        """The static rows and gremlin homes the kept plan (after ``start``) is certified
        against, else None: today's, or else those it was certified against with today's rows
        that none of those explains (:meth:`~semdp.embedded.cost_regions.Regions.unexplained_by`:
        an object not seen then), of the gremlin rows only those out of the first frame's sight
        (:meth:`~semdp.embedded.moving_certificate.KeptFrame.in_sight`). Each frame's rows
        hold every object the LiDAR sees, and neither a static object nor a gremlin's home
        moves, so a plan clear of one frame's rows is clear of those objects at every later
        step; the LiDAR's rows (every lit bin) come and go and change their bounds as the robot
        turns, and a plan certified against the last frame's alone was lost in an orbit disc
        (a gremlin candidate gone) or next to a button (its region 0.011 m wider)."""
        points, ends = plan_points(model, state, start, [kept], self.kernel)

        def certified(static: Regions, rows: Regions) -> bool:
            others = Gremlins(rows.rows, gremlins.time, gremlins.dt)
            return clearances(points, ends, state, static.rows, others, self.margin)[0] >= 0.0

        if certified(statics, homes):
            return KeptFrame(statics, homes, (state.x, state.y), gremlins.time)
        old = self._plan_seen
        if old is None:
            return None
        new = homes.unexplained_by(old.homes)
        frame = old._replace(statics=old.statics.plus(statics.unexplained_by(old.statics)),
                             homes=old.homes.plus(new.where(~old.in_sight(new))))
        return frame if certified(frame.statics, frame.homes) else None

    def _escape(self, model: RobotModel, state: RobotState, options: list[np.ndarray],
                regions: np.ndarray, contact: np.ndarray, orbit: np.ndarray) -> int:
        """The option whose step then braking keeps the largest clearance from ``regions``,
        among those that enter no region the robot is outside of now if there are any: getting
        out of one region (an orbit disc it finds itself in, a LiDAR region that lit around it)
        must not take the robot into another (a hazard)."""
        scores = [self._clearance(model, state, a, regions) for a in options]
        best = int(np.argmax(scores))
        outside = _distances(state, regions) >= regions[:, 2]
        if scores[best] < 0.0 and (contact & ~outside).any():
            return exit_option(model, state, options, regions, contact, orbit, outside,
                               self.margin, self.kernel).option
        if scores[best] >= 0.0 or not outside.any() or outside.all():
            return best
        kept = [i for i, a in enumerate(options)
                if self._clearance(model, state, a, regions[outside]) >= 0.0]
        return max(kept, key=scores.__getitem__) if kept and best not in kept else best


def _distances(state: RobotState, regions: np.ndarray) -> np.ndarray:
    """The root's distance to each region's centre (the distance of thesis Eq. 3.7)."""
    return point_distances(np.array([[state.x, state.y]]), regions[:, :2])[0]
