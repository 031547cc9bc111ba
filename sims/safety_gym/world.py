"""The physical world of a Safety Gym task: pymunk space, bodies and shapes of a layout.

Builds the world of one sampled layout (docs/simulators.md, "What is replicated": vases, pillars,
buttons, gremlins and the notched push box are physical, hazards and the goal are not), advances
it by the robot's substeps (gremlin motion and floor friction before each), collects the robot's
contacts, and makes copies continue exactly (docs/simulators.md, "Copying and checkpoints"). Hot
paths use plain Python floats: numpy calls on 2-element arrays cost more than the arithmetic.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import pymunk

from sims.safety_gym import config as cfg
from sims.safety_gym.robots import ROBOT_COLLISION_TYPE, Robot

BOX_TYPE, VASE_TYPE, PILLAR_TYPE, BUTTON_TYPE, GREMLIN_TYPE = 2, 3, 4, 5, 6
_BOX_FRICTION_RADIUS = 0.2  # effective lever arm of the box's floor friction torque (m)
_VASE_FRICTION_RADIUS = 0.077  # mean distance from the centre over a 0.2 m square


def floor_friction(body: pymunk.Body, h: float, angular_lever: float) -> None:
    """Top-down Coulomb floor friction (μ = 1) on a free body for one substep of length ``h``.

    The speed drops by μ g h (to zero, never reversing) and the spin by μ m g r h / I, with ``r``
    the friction torque's lever arm. Done in Python rather than with pymunk friction joints:
    joints keep accumulated impulses that pickling drops, so a deepcopy would not continue
    identically.
    """
    vx, vy = body.velocity
    w = body.angular_velocity
    if vx == 0.0 and vy == 0.0 and w == 0.0:
        return
    dv = cfg.FLOOR_FRICTION * cfg.GRAVITY * h
    speed = math.sqrt(vx * vx + vy * vy)
    if speed <= dv:
        body.velocity = (0.0, 0.0)
    else:
        k = 1.0 - dv / speed
        body.velocity = (vx * k, vy * k)
    dw = dv * body.mass * angular_lever / body.moment
    body.angular_velocity = 0.0 if abs(w) <= dw else w - math.copysign(dw, w)


def _square(body: pymunk.Body, cx: float, cy: float, half: float) -> pymunk.Poly:
    return pymunk.Poly(
        body,
        [(cx - half, cy - half), (cx + half, cy - half), (cx + half, cy + half),
         (cx - half, cy + half)],
    )  # fmt: skip


def push_box_outline(half: float) -> list[list[tuple[float, float]]]:
    """The notched push box: a core square [−s, s]² plus four corner squares."""
    q = half / 2
    corners = [(sx * half, sy * half) for sx in (-1, 1) for sy in (-1, 1)]
    polys = [[(-half, -half), (half, -half), (half, half), (-half, half)]]
    for cx, cy in corners:
        polys.append([(cx - q, cy - q), (cx + q, cy - q), (cx + q, cy + q), (cx - q, cy + q)])
    return polys


class PhysicsWorld:
    """Mixin of :class:`~sims.safety_gym.env.SafetyGymEnv`: the world's bodies and their motion.

    Attributes set by :meth:`_build_world`: ``space``, ``body`` (the robot), ``goal_x``,
    ``goal_y``, ``hazards``, ``pillars``, ``buttons`` (centre lists), ``vase_bodies``,
    ``box_body`` (or ``None``), ``gremlin_bodies``, ``gremlin_home``, ``gremlin_xy``.
    """

    #: Chipmunk solver iterations; they only cost time while contacts exist.
    solver_iterations: ClassVar[int] = 60

    robot: Robot
    np_random: np.random.Generator
    pillar_radius: float
    box_half: float
    box_mass: float
    space: pymunk.Space | None
    sim_time: float
    _touched: list[pymunk.Shape]
    _needs_contacts: bool

    def _build_world(
        self, layout: Mapping[str, list[tuple[float, float]]], agent_yaw: float
    ) -> None:
        rng = self.np_random
        space = pymunk.Space()
        space.collision_slop = 0.001
        # the push box is 40-2000x lighter than the robots: more solver iterations keep a box
        # squeezed between a robot and a pillar from being overrun (tests/test_sims_physics.py)
        space.iterations = self.solver_iterations
        self.space = space
        ax, ay = layout["agent"][0]
        self.body = self.robot.build(space, ax, ay, agent_yaw)
        self.goal_x, self.goal_y = layout["goal"][0] if "goal" in layout else (0.0, 0.0)
        self.hazards = list(layout.get("hazards", []))
        self.pillars = list(layout.get("pillars", []))
        self.buttons = list(layout.get("buttons", []))
        self._pillar_shapes = []
        for px, py in self.pillars:
            shape = pymunk.Circle(space.static_body, self.pillar_radius, (px, py))
            shape.collision_type, shape.friction = PILLAR_TYPE, 1.0
            space.add(shape)
            self._pillar_shapes.append(shape)
        self._button_shapes = []
        for bx, by in self.buttons:
            shape = pymunk.Circle(space.static_body, cfg.BUTTON_RADIUS, (bx, by))
            shape.collision_type, shape.friction = BUTTON_TYPE, 1.0
            space.add(shape)
            self._button_shapes.append(shape)
        self.vase_bodies = []
        for vx, vy in layout.get("vases", []):
            body = pymunk.Body(cfg.VASE_MASS, pymunk.moment_for_box(cfg.VASE_MASS, (0.2, 0.2)))
            body.position, body.angle = (vx, vy), float(rng.uniform(0.0, 2 * math.pi))
            shape = _square(body, 0.0, 0.0, cfg.VASE_HALF)
            shape.collision_type, shape.friction = VASE_TYPE, 1.0
            space.add(body, shape)
            self.vase_bodies.append(body)
        self.box_body = None
        if "push_box" in layout:
            bx, by = layout["push_box"][0]
            half, mass = self.box_half, self.box_mass
            # Izz 7.25e-6 for the Point's box, scaled by mass and size squared
            body = pymunk.Body(mass, 7.25e-6 * (mass / 1.28e-4) * (half / 0.2) ** 2)
            body.position, body.angle = (bx, by), float(rng.uniform(0.0, 2 * math.pi))
            shapes = [pymunk.Poly(body, poly) for poly in push_box_outline(half)]
            for shape in shapes:
                shape.collision_type, shape.friction = BOX_TYPE, 1.0
            space.add(body, *shapes)
            self.box_body = body
        self._free_bodies = [(b, _VASE_FRICTION_RADIUS) for b in self.vase_bodies]
        if self.box_body is not None:
            self._free_bodies.append((self.box_body, _BOX_FRICTION_RADIUS * self.box_half / 0.2))
        self.gremlin_bodies = []
        self.gremlin_home = list(layout.get("gremlins", []))
        self.gremlin_xy = [list(p) for p in self.gremlin_home]
        for gx, gy in self.gremlin_home:
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position, body.angle = (gx, gy), float(rng.uniform(0.0, 2 * math.pi))
            shape = _square(body, 0.0, 0.0, cfg.GREMLIN_HALF)
            shape.collision_type, shape.friction = GREMLIN_TYPE, 1.0
            space.add(body, shape)
            self.gremlin_bodies.append(body)
        self._gremlin_decay = math.exp(-self.robot.h / cfg.GREMLIN_LAG_S)

    # ------------------------------------------------------------------ motion
    def _advance_physics(self, a0: float, a1: float) -> tuple[float, float, float, float]:
        """Apply the action for the robot's substeps; return its ``(x, y, vx, vy)`` after them.

        Before each substep the gremlins move and floor friction acts on the free bodies;
        ``_last_accel`` becomes the robot's world-frame acceleration over the last substep.
        """
        robot, body, space = self.robot, self.body, self.space
        robot.set_action(a0, a1)
        h = robot.h
        gremlins = self.gremlin_bodies
        free = self._free_bodies
        vx0 = vy0 = 0.0
        for _ in range(robot.substeps):
            if gremlins:
                self._move_gremlins(h)
            if free:
                for free_body, lever in free:
                    floor_friction(free_body, h, lever)
            vx0, vy0 = robot.substep(body)
            space.step(h)
            self.sim_time += h
        vx, vy = body.velocity
        self._last_accel = ((vx - vx0) / h, (vy - vy0) / h)
        rx, ry = body.position
        return rx, ry, vx, vy

    def _collect_contacts(self) -> list[pymunk.Shape]:
        """The shapes touching the robot now; only gathered in tasks with contact rules.

        The same list is refilled every step (Button presses, vases in Goal2 and pillars in
        Push2 need contacts; other tasks get it empty).
        """
        touched = self._touched
        touched.clear()
        if self._needs_contacts:
            self.body.each_arbiter(self._record_arbiter)
        return touched

    def _record_arbiter(self, arbiter: pymunk.Arbiter) -> None:
        a, b = arbiter.shapes
        self._touched.append(b if a.collision_type == ROBOT_COLLISION_TYPE else a)

    def _move_gremlins(self, h: float) -> None:
        """Gremlin law: track placement + 0.35 (sin t, cos t), 0.09 s lag (docs/simulators.md)."""
        t = self.sim_time + h
        ox, oy = cfg.GREMLIN_TRAVEL * math.sin(t), cfg.GREMLIN_TRAVEL * math.cos(t)
        e = self._gremlin_decay
        inv_h = 1.0 / h
        for (hx, hy), xy, body in zip(
            self.gremlin_home, self.gremlin_xy, self.gremlin_bodies, strict=True
        ):
            tx, ty = hx + ox, hy + oy
            nx, ny = tx + (xy[0] - tx) * e, ty + (xy[1] - ty) * e
            body.velocity = ((nx - xy[0]) * inv_h, (ny - xy[1]) * inv_h)
            xy[0], xy[1] = nx, ny

    # ------------------------------------------------------------------ copying
    _PHYSICS_ATTRS = (
        "space", "body", "box_body", "vase_bodies", "gremlin_bodies", "_pillar_shapes",
        "_button_shapes", "_free_bodies",
    )  # fmt: skip

    def __getstate__(self) -> dict[str, Any]:
        """Pickle/deepcopy support with exact continuation.

        pymunk restores a space with a rebuilt spatial index, so the solver visits contacts in
        a different order than the original and the two drift apart (~1e-5 m per contact step,
        then chaotically). Before its state is taken, the env therefore replaces its own
        physics objects by a pickled round trip: original and copy then hold identically
        restored worlds and continue bit for bit. A checkpoint thus perturbs the original by
        that round trip: runs are reproducible given the same checkpoint schedule.
        """
        if self.space is not None:
            fresh = copy.deepcopy({k: self.__dict__[k] for k in self._PHYSICS_ATTRS})
            self.__dict__.update(fresh)
        return self.__dict__.copy()
