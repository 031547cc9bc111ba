"""The safety filter's way out of a cost region it is inside (beyond the thesis, §3.5.2; the
escape of :class:`~semdp.embedded.shield.SafetyShield`).

**Inside a contact region** (the Button tasks' grace period: the robot starts it touching the
button it just pressed, which is a wrong button once the goal moves; a push that left it near a
pillar) one step then braking barely moves a robot at rest, so the escape cannot tell a way out
from a turn on the spot. There the escape plans :data:`EXIT_STEPS` steps ahead, each option
held for 1 to :data:`EXIT_STEPS` steps and then braking (an :class:`ExitPlan`), and takes the
plan that gets farthest out of the static regions it is in (a button, not a gremlin's orbit
disc, which it may be deep inside), then out of all, with gaps measured from the robot's
outline at its predicted heading rather than from a disc of its extent, among the plans that
enter no other region by more than the margin, else those that enter least
(:func:`exit_option`, with the trained runs' episodes that led to each part): with
goal-seeking subgoals the Point's nose, swinging back into the button as the robot turned away,
touched it after the grace period in 1 of 60 episodes on Button1 before the hold and the
outline. Plans that stop short of the horizon are what a robot between two regions needs: a
Car that had pressed a button with its rear, a hazard 0.3 m ahead of the button's region, found
every whole-horizon hold either back on the button or into the hazard's region; re-ranked every
step, full forward and full reverse alternated in place until the grace period ended
(``cost_buttons`` after it, a trained CarButton1 run's epoch 51), while forward for a few steps
then braking leaves the button and stops short of the hazard, and one step later the same plan,
a step shorter, still ranks first.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from semdp.embedded.plan_rollouts import rollout
from semdp.embedded.robot_models import RobotModel, RobotState
from solvers.planner.geometry import point_distances

#: Steps an escape from inside a region is held in :func:`exit_option`'s rollouts: the Button
#: task's grace period after a press (``BUTTON_RESAMPLING_DELAY``), within which the robot must
#: be off the button it pressed.
EXIT_STEPS = 10


class ExitPlan(NamedTuple):
    """Option ``option`` (an index into the escape's options) held for ``hold`` steps, then
    braking until :data:`EXIT_STEPS` steps have passed."""

    option: int
    hold: int


def exit_option(model: RobotModel, state: RobotState, options: list[np.ndarray],
                regions: np.ndarray, contact: np.ndarray, orbit: np.ndarray,
                outside: np.ndarray, margin: float, kernel: str = "native") -> ExitPlan:
    """Inside a region (a button just pressed, an orbit disc, a LiDAR region lit around the
    robot): the plan (an option held for 1 to :data:`EXIT_STEPS` steps, then braking) that
    gets farthest out of the static regions it is in (every kind but a gremlin's orbit disc),
    then farthest out of all the regions it is in, at the best step of its :data:`EXIT_STEPS`;
    among the plans that enter no region the robot is outside of (by more than ``margin`` when
    it is that deep in a static region) if there are any, else among those that enter least.
    The escape applies the plan's option now and plans again at the next step.

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
    swing, which a disc cannot tell.

    Args:
        model, state: the bound robot's model and its state now.
        options: the actions to choose from (braking and the model's escapes).
        regions: rows ``[x, y, R]`` (the filter's cost regions near the robot).
        contact, orbit, outside: per row, whether its cost is a contact with the robot's
            outline, whether it is a gremlin's orbit disc, whether the robot is outside it now.
        margin: the filter's margin (m).
        kernel: how the plans are rolled out (:func:`~semdp.embedded.plan_rollouts.rollout`).
    """
    poses = _hold_then_brake(model, state, options, kernel)
    n_plans = len(poses)
    flat = poses.reshape(-1, 3)
    gaps = point_distances(flat[:, :2], regions[:, :2]) - regions[:, 2]
    exiting = contact & ~outside
    if exiting.any():  # R without the robot's extent, from the outline
        gaps[:, exiting] = model.outline.distance(
            flat[:, 0], flat[:, 1], flat[:, 2], regions[exiting, :2]) - (
            regions[exiting, 2] - model.extent)
    gaps = gaps.reshape(n_plans, EXIT_STEPS, -1)
    depth = gaps[:, :, ~outside].min(axis=2).max(axis=1)
    static = ~outside & ~orbit
    static_depth = (gaps[:, :, static].min(axis=2).max(axis=1) if static.any()
                    else np.zeros(n_plans))
    entries = (gaps[:, :, outside].min(axis=(1, 2)) if outside.any()
               else np.zeros(n_plans))
    tolerance = margin if _static_depth_now(model, state, regions, contact,
                                            static) < -margin else 0.0
    kept = [i for i in range(n_plans) if entries[i] >= -tolerance]
    if not kept:
        kept = [i for i in range(n_plans) if entries[i] == entries.max()]
    best = max(kept, key=lambda i: (static_depth[i], depth[i]))
    return ExitPlan(best // EXIT_STEPS, best % EXIT_STEPS + 1)


def _hold_then_brake(model: RobotModel, state: RobotState, options: list[np.ndarray] | np.ndarray,
                     kernel: str = "native", steps: int = EXIT_STEPS) -> np.ndarray:
    """Poses ``(len(options) * EXIT_STEPS, steps, 3)`` (x, y, yaw after each step): row
    ``i * EXIT_STEPS + j - 1`` holds option ``i`` for ``j`` steps, then brakes
    (``model.backup``) for the remaining ``steps - j``: the exit's plans, the model's steps,
    rolled out together (:func:`~semdp.embedded.plan_rollouts.rollout`)."""
    actions = np.repeat(np.asarray(options, dtype=np.float64).reshape(-1, 2), EXIT_STEPS, axis=0)
    holds = np.tile(np.arange(1, EXIT_STEPS + 1), len(actions) // EXIT_STEPS)
    return rollout(model, state, None, actions, holds, steps, with_yaw=True, kernel=kernel)


def _static_depth_now(model: RobotModel, state: RobotState, regions: np.ndarray,
                      contact: np.ndarray, static: np.ndarray) -> float:
    """The robot's gap out of the static regions it is in, where it is now (contact regions
    from its outline, as in :func:`exit_option`); ``inf`` if it is in none."""
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


_EXIT_REACH: dict[type, float] = {}


def exit_reach(model: RobotModel) -> float:
    """How far (m) an exit from rest can take the robot's root: the farthest point of any
    escape held for 1 to :data:`EXIT_STEPS` steps and then braked to rest (a press stops the
    robot against the button). Once per robot class, from the model's rollouts."""
    if type(model) not in _EXIT_REACH:
        points = _hold_then_brake(model, RobotState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                                  model.escapes, "python", EXIT_STEPS + model.horizon)[..., :2]
        _EXIT_REACH[type(model)] = float(np.sqrt((points ** 2).sum(axis=-1)).max())
    return _EXIT_REACH[type(model)]


def presses_without_exit(model: RobotModel, state: RobotState, goal: np.ndarray,
                         orbits: np.ndarray, margin: float, kernel: str = "native") -> np.ndarray:
    """Per row of ``goal`` (the goal button's contact regions ``[x, y, R]``), whether the robot
    must not press it, with gremlins' orbit discs ``orbits`` about (the moving-gremlin
    certificate, :mod:`semdp.embedded.moving_certificate`).

    A press stops the robot against the button; the goal moves and the button becomes a wrong
    one, to leave within the grace period by this module's exit, which ranks the discs as
    regions and knows nothing of the gremlins' timing: it is safe as long as it can leave
    without entering a disc. So, with the robot outside every disc (inside one, the certified
    plans keep it off the goal button), a press is refused where the button lies within the
    exit's reach (:func:`exit_reach` plus ``margin``) of a disc and, pressed and at rest (on the
    line from the button to the robot, ``R - margin`` from the button's centre: where the touch
    ends), no exit plan (braking or an escape held 1 to :data:`EXIT_STEPS` steps, then braked to
    rest) is off the button at the grace period's end without entering a disc on the way. A
    trained PointButton1 run pressed the goal button 0.015 m outside a disc, in a pocket
    between two; its way out entered a disc, and the gremlin touched it 41 steps after the
    press (tests/test_moving_gremlins.py)."""
    refused = np.zeros(len(goal), dtype=bool)
    if not len(goal) or not len(orbits) or (
            point_distances(np.array([[state.x, state.y]]), orbits[:, :2])[0]
            < orbits[:, 2]).any():
        return refused
    reach = exit_reach(model) + margin
    near = (point_distances(goal[:, :2], orbits[:, :2])
            < goal[:, None, 2] + reach + orbits[None, :, 2]).any(axis=1)
    for i in np.flatnonzero(near):
        row = goal[i]
        dx, dy = state.x - row[0], state.y - row[1]
        touch = row[2] - margin
        scale = touch / max(math.hypot(dx, dy), 1e-9)
        pose = RobotState(row[0] + dx * scale, row[1] + dy * scale, 0.0, 0.0, state.yaw, 0.0)
        options = np.concatenate([np.asarray(model.backup(pose))[None], model.escapes])
        points = _hold_then_brake(model, pose, options, kernel,
                                  EXIT_STEPS + model.horizon)[..., :2]
        in_disc = point_distances(points.reshape(-1, 2), orbits[:, :2]) - orbits[:, 2]
        clear = in_disc.min(axis=1).reshape(len(points), -1).min(axis=1) >= 0.0
        off = point_distances(points[:, EXIT_STEPS - 1], row[None, :2])[:, 0] >= touch
        refused[i] = not (clear & off).any()
    return refused
