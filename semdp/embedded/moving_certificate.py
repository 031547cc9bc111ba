"""The safety filter's certificate against gremlins where they are, not where they may be
(beyond the thesis, §3.5.2; ``SafetyShield(gremlins="moving")``).

The static certificate (:mod:`semdp.embedded.shield`) keeps the robot out of each gremlin's
whole orbit disc, because braking leaves it at rest and a robot at rest inside the disc is hit
when the gremlin comes round. The gremlin law (:mod:`semdp.embedded.perception`) says more:
every gremlin sits at ``home + o(t)`` at episode time ``t``, ``o`` known in closed form
(within :data:`~semdp.embedded.perception.GREMLIN_LAW_TOLERANCE`). So a robot may cross a
disc while its gremlin is elsewhere on the orbit, if it can always get out again in time.

**The certificate.** A *plan* holds one of the robot's escape actions for ``hold`` steps
(:data:`HOLDS`) and then brakes (:func:`~semdp.embedded.plan_rollouts.rollout`, the filter's
robot model). A plan is certified when, at every env step of it, the robot's disc of extent
is out of every gremlin's body at that step's time (``home + o(t_k)``, the region's radius
less the orbit's travel), out of every static region it is outside of now (and of the goal
button's contact region: the plans model no contacts, and a robot that presses the button
stops against it and must leave it, a wrong button once the goal moves, within the grace
period, with the gremlin coming round), no deeper than now
(or the margin) in a static region it is inside now and out of that one too from
:data:`~semdp.embedded.exit_planning.EXIT_STEPS` on (the Button tasks' grace period), and
when the plan **ends at rest outside every orbit disc**. A robot at rest there is safe
forever by the static argument. The proposed action is kept if it is certified as the first
step of some plan; otherwise the robot follows a plan certified from where it is. The plan
certified at one step is, one step shorter, certified at the next (the same trajectory under
the model), so by induction a certified plan exists at every step once one did: the filter
keeps the last one and tries it alone first (one rollout), then the whole set. The induction
needs the objects the plan was certified against, not the next LiDAR frame's rows (every lit
bin is one; they come and go, and their bounds change, as the robot turns): the kept plan is
checked against today's rows, else against those it was certified against plus today's rows
that may hold an object none of those holds
(:meth:`~semdp.embedded.cost_regions.Regions.unexplained_by`: an object not seen then; static
objects and gremlins' homes do not move) and, for a gremlin row, a gremlin out of the LiDAR's
range when the first of those frames was read (:meth:`KeptFrame.in_sight`: every gremlin in
range lit a row of it). Where none is certified (a contact, a gremlin seen
late) the filter takes the plan with the largest clearance inside an orbit disc, and its static
rules outside.

The bounds relied on: the robot model's one-step error and the gremlin law's tolerance within
the filter's margin, as for the static certificate; the layout's placement keepouts (two
objects' centres at least the sum of their kinds' keepouts apart) for telling a row's object
from another's; the LiDAR's law (:mod:`semdp.embedded.lidar_bounds`: an object within range is
its bin's largest contribution) for a frame holding every gremlin in range; gaps are checked
at env steps.
tests/test_moving_gremlins.py plants robots that cross orbit discs and a check that ignores
the gremlins' motion (fails: contact), and kept frames that explain gremlin rows out of their
sight (fails: a plan kept against a gremlin never seen).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from semdp.embedded.cost_regions import Regions
from semdp.embedded.exit_planning import EXIT_STEPS
from semdp.embedded.lidar_bounds import LIDAR_RANGE
from semdp.embedded.perception import GREMLIN_LAW_TOLERANCE, GREMLIN_TRAVEL, gremlin_offsets
from semdp.embedded.plan_rollouts import rollout
from semdp.embedded.robot_models import RobotModel, RobotState

#: The hold lengths (env steps) of the plans tried with each escape action.
HOLDS: tuple[int, ...] = (0, 2, 5, 10, 20, 35, 50)
#: How far (m) inside the LiDAR's range an object must be to be sure to light its bin: the
#: float32 reading and the empty-bin threshold move the range's edge by less than 1e-5 m.
SIGHT_SLACK = 1e-3


@dataclass(frozen=True)
class Plan:
    """Hold ``action`` for ``hold`` env steps, then brake."""

    action: tuple[float, float]
    hold: int

    def shorter(self) -> Plan:
        """The same plan one step later."""
        return Plan(self.action, max(self.hold - 1, 0))


@dataclass(frozen=True)
class Gremlins:
    """What the certificate needs of the gremlins: their homes' rows ``[x, y, R]`` (``R``:
    the orbit disc's radius, :func:`~semdp.embedded.perception.gremlin_orbits` plus the
    robot's extent and margin), the episode time now and the env step's length (s)."""

    homes: np.ndarray
    time: float
    dt: float

    def centres(self, steps: int) -> np.ndarray:
        """``(steps, g, 2)``: each gremlin's centre after each of the next ``steps`` steps."""
        offsets = gremlin_offsets(self.time + self.dt * np.arange(1, steps + 1))
        return self.homes[None, :, :2] + offsets[:, None, :]


class KeptFrame(NamedTuple):
    """What the kept plan was certified against: static rows and gremlin homes, and where
    (the robot's root) and when (episode time, s) the LiDAR frame they began with was read."""

    statics: Regions
    homes: Regions
    position: tuple[float, float]
    time: float

    def in_sight(self, homes: Regions) -> np.ndarray:
        """``(m,)``: whether every gremlin that row ``i`` of ``homes`` may hold was within the
        LiDAR's range (less :data:`SIGHT_SLACK`) when this frame was read. The gremlin was
        then at ``home + o(time)`` (within the law's tolerance), its home within the row's
        spread of the row's centre. Such a gremlin lit a bin of that frame (the LiDAR reads
        object centres; under the law of :mod:`semdp.embedded.lidar_bounds` as its bin's
        largest contribution), and every lit bin is a row of the frame: the plan was
        certified against it."""
        body = homes.rows[:, :2] + gremlin_offsets(np.array([self.time]))[0]
        far = (np.hypot(body[:, 0] - self.position[0], body[:, 1] - self.position[1])
               + homes.spread + GREMLIN_LAW_TOLERANCE)
        return far < LIDAR_RANGE - SIGHT_SLACK


def plans_for(model: RobotModel) -> list[Plan]:
    """Every escape action at every hold of :data:`HOLDS` (braking once)."""
    plans = [Plan((0.0, 0.0), 0)]
    return plans + [Plan((float(a[0]), float(a[1])), h) for a in model.escapes for h in HOLDS
                    if h]


def certified_plans(model: RobotModel, state: RobotState, first: np.ndarray | None,
                    plans: list[Plan], static: np.ndarray, gremlins: Gremlins,
                    margin: float, kernel: str = "native") -> np.ndarray:
    """Each plan's clearance (m; ``>= 0``: certified, module docstring), after ``first`` if
    given, until it is at rest (its hold, then the model's braking horizon). ``static``: rows
    ``[x, y, R]`` of the regions that do not move. The plans are rolled out by
    :func:`~semdp.embedded.plan_rollouts.rollout` with ``kernel``."""
    points, ends = plan_points(model, state, first, plans, kernel)
    return clearances(points, ends, state, static, gremlins, margin)


def plan_points(model: RobotModel, state: RobotState, first: np.ndarray | None,
                plans: list[Plan], kernel: str = "native") -> tuple[np.ndarray, np.ndarray]:
    """``(points, ends)``: the root after each step of each plan (after ``first`` if given),
    ``(n, steps, 2)``, plan ``i`` at rest after its first ``ends[i]`` steps (its hold, then the
    model's braking horizon); :func:`clearances` scores them."""
    holds = np.array([p.hold for p in plans])
    ends = (first is not None) + holds + model.horizon
    return rollout(model, state, first, np.array([p.action for p in plans]), holds,
                   int(ends.max()), kernel=kernel), ends


def clearances(points: np.ndarray, ends: np.ndarray, state: RobotState, static: np.ndarray,
               gremlins: Gremlins, margin: float) -> np.ndarray:
    """The certificate (module docstring) of trajectories ``points`` ``(n, steps, 2)`` from
    ``state``, trajectory ``i`` at rest after its first ``ends[i]`` steps: each one's smallest
    gap (m; ``>= 0``: certified)."""
    n, steps, _ = points.shape
    valid = np.arange(steps)[None, :] < ends[:, None]                    # (n, steps)
    clearance = np.full(n, np.inf)
    travel = float(np.sqrt(((points - (state.x, state.y)) ** 2).sum(axis=-1)).max())
    if len(static):  # only the regions the trajectories can reach
        static = static[np.hypot(static[:, 0] - state.x, static[:, 1] - state.y)
                        - static[:, 2] <= travel]
    if len(static):
        gaps = np.hypot(points[:, :, None, 0] - static[:, 0], points[:, :, None, 1]
                        - static[:, 1]) - static[:, 2]                  # (n, steps, m)
        now = np.hypot(static[:, 0] - state.x, static[:, 1] - state.y) - static[:, 2]
        floor = np.where(now >= 0.0, 0.0, np.minimum(now, -margin))
        late = np.arange(steps) >= EXIT_STEPS - 1
        floor = np.where(late[:, None] & (now < 0.0)[None, :], 0.0, floor[None, :])
        worst = np.where(valid, (gaps - floor[None]).min(axis=2), np.inf)
        clearance = np.minimum(clearance, worst.min(axis=1))
    homes = gremlins.homes
    if len(homes):
        bodies = gremlins.centres(steps)                                # (steps, g, 2)
        gaps = np.hypot(points[:, :, None, 0] - bodies[None, :, :, 0],
                        points[:, :, None, 1] - bodies[None, :, :, 1])
        worst = np.where(valid, (gaps - (homes[:, 2] - GREMLIN_TRAVEL)).min(axis=2), np.inf)
        clearance = np.minimum(clearance, worst.min(axis=1))
        end = points[np.arange(n), ends - 1]                            # (n, 2)
        clearance = np.minimum(clearance, (np.hypot(end[:, None, 0] - homes[:, 0],
                                                    end[:, None, 1] - homes[:, 1])
                                           - homes[:, 2]).min(axis=1))
    return clearance


def choose(plans: list[Plan], clearance: np.ndarray) -> Plan | None:
    """The certified plan with the largest clearance (None if none is certified)."""
    best = int(np.argmax(clearance))
    return plans[best] if clearance[best] >= 0.0 else None
