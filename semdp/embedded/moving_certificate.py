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
less the orbit's travel), out of every static region it is outside of now, no deeper than now
(or the margin) in a static region it is inside now and out of that one too from
:data:`~semdp.embedded.exit_planning.EXIT_STEPS` on (the Button tasks' grace period), and
when the plan **ends at rest outside every orbit disc**. A robot at rest there is safe
forever by the static argument. The proposed action is kept if it is certified as the first
step of some plan; otherwise the robot follows a plan certified from where it is. The plan
certified at one step is, one step shorter, certified at the next (the same trajectory under
the model), so by induction a certified plan exists at every step once one did: the filter
keeps the last one and tries it first. Where none is certified (a contact, a gremlin seen late)
the filter falls back to its static rules.

The bound relied on: the robot model's one-step error and the gremlin law's tolerance within
the filter's margin, as for the static certificate; gaps are checked at env steps.
tests/test_moving_gremlins.py plants robots that cross orbit discs and a check that ignores
the gremlins' motion (fails: contact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from semdp.embedded.exit_planning import EXIT_STEPS
from semdp.embedded.perception import GREMLIN_TRAVEL, gremlin_offset
from semdp.embedded.plan_rollouts import rollout
from semdp.embedded.robot_models import RobotModel, RobotState

#: The hold lengths (env steps) of the plans tried with each escape action.
HOLDS: tuple[int, ...] = (0, 2, 5, 10, 20, 35, 50)


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
        offsets = np.array([gremlin_offset(self.time + (k + 1) * self.dt)
                            for k in range(steps)])
        return self.homes[None, :, :2] + offsets[:, None, :]


def plans_for(model: RobotModel, kept: Plan | None) -> list[Plan]:
    """Every escape action at every hold of :data:`HOLDS` (braking once), and ``kept``."""
    plans = [Plan((0.0, 0.0), 0)]
    plans += [Plan((float(a[0]), float(a[1])), h) for a in model.escapes for h in HOLDS if h]
    if kept is not None and kept not in plans:
        plans.append(kept)
    return plans


def certified_plans(model: RobotModel, state: RobotState, first: np.ndarray | None,
                    plans: list[Plan], static: np.ndarray, gremlins: Gremlins,
                    margin: float) -> np.ndarray:
    """Each plan's clearance (m; ``>= 0``: certified, module docstring), after ``first`` if
    given. ``static``: rows ``[x, y, R]`` of the regions that do not move."""
    steps = (first is not None) + max(p.hold for p in plans) + model.horizon
    actions = np.array([p.action for p in plans])
    holds = np.array([p.hold for p in plans])
    points = rollout(model, state, first, actions, holds, steps)        # (n, steps, 2)
    clearance = np.full(len(plans), np.inf)
    if len(static):
        gaps = np.linalg.norm(points[:, :, None, :] - static[None, None, :, :2], axis=-1)
        gaps -= static[:, 2]                                            # (n, steps, m)
        now = np.hypot(static[:, 0] - state.x, static[:, 1] - state.y) - static[:, 2]
        floor = np.where(now >= 0.0, 0.0, np.minimum(now, -margin))
        late = np.arange(steps) >= EXIT_STEPS - 1
        floor = np.where(late[:, None] & (now < 0.0)[None, :], 0.0, floor[None, :])
        clearance = np.minimum(clearance, (gaps - floor[None]).min(axis=(1, 2)))
    homes = gremlins.homes
    if len(homes):
        bodies = gremlins.centres(steps)                                # (steps, g, 2)
        gaps = np.linalg.norm(points[:, :, None, :] - bodies[None], axis=-1)
        gaps -= homes[:, 2] - GREMLIN_TRAVEL
        clearance = np.minimum(clearance, gaps.min(axis=(1, 2)))
        end = np.linalg.norm(points[:, -1, None, :] - homes[None, :, :2], axis=-1)
        clearance = np.minimum(clearance, (end - homes[:, 2]).min(axis=1))
    return clearance


def choose(plans: list[Plan], clearance: np.ndarray, kept: Plan | None) -> Plan | None:
    """``kept`` if it is certified, else the certified plan with the largest clearance."""
    if kept is not None and kept in plans and clearance[plans.index(kept)] >= 0.0:
        return kept
    best = int(np.argmax(clearance))
    return plans[best] if clearance[best] >= 0.0 else None
