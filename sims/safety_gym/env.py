"""The Safety Gym replica environment: robot x task x level on a pymunk plane (SPEC §3.1).

Step order follows Safety-Gymnasium's ``builder.step`` (spec §1): clip the action, run the
physics substeps (gremlins moved before each), reward, cost, button-timer tick, goal check and
resampling (the episode continues), observation. Hot paths use plain Python floats and lists:
numpy calls on 2- to 16-element arrays cost more than the arithmetic they do.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar

import gymnasium
import numpy as np
import pymunk

from sims.safety_gym import config as cfg
from sims.safety_gym.layout import LayoutError, sample_goal, sample_layout
from sims.safety_gym.lidar import fill_pseudo_lidar
from sims.safety_gym.robots import ROBOT_CLASSES, ROBOT_COLLISION_TYPE, Robot

BOX_TYPE, VASE_TYPE, PILLAR_TYPE, BUTTON_TYPE, GREMLIN_TYPE = 2, 3, 4, 5, 6
OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins", "buttons")
DEFAULT_OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins")
LAYOUT_KEYS: tuple[str, ...] = (
    "agent", "agent_yaw", "goal", "hazards", "vases", "pillars", "push_box", "buttons", "gremlins",
)  # fmt: skip
_SQRT2 = math.sqrt(2.0)
_BOX_FRICTION_RADIUS = 0.2  # effective lever arm of the box's floor friction torque (m)
_VASE_FRICTION_RADIUS = 0.077  # mean distance from the centre over a 0.2 m square


def _floor_friction(body: pymunk.Body, h: float, angular_lever: float) -> None:
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
    """The notched push box: a core square [−s, s]² plus four corner squares (spec §4)."""
    q = half / 2
    corners = [(sx * half, sy * half) for sx in (-1, 1) for sy in (-1, 1)]
    polys = [[(-half, -half), (half, -half), (half, half), (-half, half)]]
    for cx, cy in corners:
        polys.append([(cx - q, cy - q), (cx + q, cy - q), (cx + q, cy + q), (cx - q, cy + q)])
    return polys


class SafetyGymEnv(gymnasium.Env):
    """Safety Gym task for one robot at one level (SPEC §3.1; spec file §1-§11).

    Args:
        robot: ``"point"``, ``"car"`` or ``"mass"``. A robot-only, obstacle-free world is
            ``task="goal", level=0`` (only the virtual goal exists).
        task: ``"goal"``, ``"button"`` or ``"push"``.
        level: 0, 1 or 2.
        render_mode: ``None`` or ``"rgb_array"`` (top-down frames).
        render_size: frame side in pixels.
        sizes: optional overrides of ``hazard_radius``, ``pillar_radius``, ``box_half`` and
            ``goal_size`` (m), and ``robot_scale`` (factor on the robot's collision shapes
            about its root; mass, inertia, actuators and sensors stay nominal) for perturbed
            variants; the defaults are the spec's (``robot_scale`` 1.0).

    Reset options: ``{"layout": {...}}`` plants positions: ``"agent": (x, y)``,
    ``"agent_yaw": float`` and, per object type, a list of ``(x, y)`` (its length may differ
    from the spec's count). Unplanted objects are sampled clear of the planted ones.

    ``step`` returns the gymnasium 5-tuple; ``info["cost"]`` is the 0/1 indicator (spec §8),
    beside the named terms of the constrained objects (``cost_hazards``, ``cost_vases_contact``,
    ``cost_vases_velocity``, ``cost_pillars``, ``cost_gremlins``, ``cost_buttons``) and
    ``cost_sum`` (= ``cost``), plus ``goal_met``.
    """

    #: Chipmunk solver iterations; they only cost time while contacts exist.
    solver_iterations: ClassVar[int] = 60
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(
        self,
        robot: str = "point",
        task: str = "goal",
        level: int = 1,
        render_mode: str | None = None,
        render_size: int = 256,
        sizes: Mapping[str, float] | None = None,
    ) -> None:
        cfg.validate(robot, task, level)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r}; valid: None, 'rgb_array'")
        self.robot_name, self.task, self.level = robot, task, level
        self.render_mode = render_mode
        self.render_size = int(render_size)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / ROBOT_CLASSES[robot].dt)}
        self.robot: Robot = ROBOT_CLASSES[robot]()
        self.layout_spec = cfg.level_spec(task, level, robot)
        objs = self.layout_spec.objects
        self.hazard_radius = cfg.HAZARD_RADIUS[task]
        self.goal_size = cfg.BUTTON_GOAL_SIZE if task == "button" else cfg.GOAL_SIZE
        self.box_half, self.box_mass = cfg.BOX_GEOMETRY[robot]
        self.pillar_radius = cfg.PILLAR_RADIUS
        self.robot_scale = 1.0
        self._apply_sizes(sizes)
        self._constrained = {k: v.constrained for k, v in objs.items()}
        self._cost_keys = self._make_cost_keys()
        # contact-based costs or rewards: Button presses, vases (Goal2), pillars (Push2)
        self._needs_contacts = task == "button" or level == 2
        self._contact_costs = any(k != "cost_hazards" for k in self._cost_keys)

        # observation layout (spec §9.3): sensors, then LiDAR channels in insertion order
        slices: dict[str, slice] = {}
        n = 0
        for name, size in self.robot.sensor_sizes:
            slices[name] = slice(n, n + size)
            n += size
        self._n_sensors = n
        self._lidar_offsets: dict[str, int] = {}
        for kind in self.layout_spec.lidar_order:
            slices[f"{kind}_lidar"] = slice(n, n + cfg.LIDAR_BINS)
            self._lidar_offsets[kind] = n
            n += cfg.LIDAR_BINS
        self.obs_slices: dict[str, slice] = slices
        low = np.full(n, -np.inf)
        high = np.full(n, np.inf)
        low[self._n_sensors :] = 0.0
        high[self._n_sensors :] = 1.0
        self.observation_space = gymnasium.spaces.Box(low, high, dtype=np.float64)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (2,), dtype=np.float64)
        self._obs_size = n
        self._overlay_waypoints: np.ndarray | None = None
        self._overlay_subgoal: np.ndarray | None = None
        self.space: pymunk.Space | None = None

    # ------------------------------------------------------------------ construction
    SIZE_KEYS: ClassVar[tuple[str, ...]] = (
        "hazard_radius",
        "pillar_radius",
        "box_half",
        "goal_size",
        "robot_scale",
    )

    def _apply_sizes(self, sizes: Mapping[str, float] | None) -> None:
        """Override object sizes (for perturbed variants, e.g. a real-robot-like Push).

        Keepouts stay the spec's; the box mass scales with its area (constant density).
        ``robot_scale`` scales the robot's collision shapes only (``Robot.scale``): its mass
        and inertia stay nominal, so the calibrated actuator response is unchanged; the hazard
        cost (root inside the disc), the rewards (positions) and the LiDAR origin (the root)
        do not depend on the shape.
        """
        if not sizes:
            return
        bad = set(sizes) - set(self.SIZE_KEYS)
        if bad:
            raise ValueError(f"unknown size keys {sorted(bad)}; valid: {list(self.SIZE_KEYS)}")
        for key, value in sizes.items():
            try:
                value = float(value)
            except (TypeError, ValueError) as err:
                raise ValueError(
                    f"sizes[{key!r}] must be a positive number, got {value!r}") from err
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"sizes[{key!r}] must be a positive number, got {value!r}")
            if key == "box_half":
                self.box_mass *= (value / self.box_half) ** 2
            elif key == "robot_scale":
                self.robot.scale = value
            setattr(self, key, value)

    def _make_cost_keys(self) -> tuple[str, ...]:
        keys = []
        if self._constrained.get("hazards"):
            keys.append("cost_hazards")
        if self._constrained.get("vases"):
            keys += ["cost_vases_contact", "cost_vases_velocity"]
        if self._constrained.get("pillars"):
            keys.append("cost_pillars")
        if self._constrained.get("gremlins"):
            keys.append("cost_gremlins")
        if self._constrained.get("buttons"):
            keys.append("cost_buttons")
        return tuple(keys)

    def _build_world(self, layout: Mapping[str, list[tuple[float, float]]], agent_yaw: float):
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
            # Izz 7.25e-6 for the Point's box (spec §4), scaled by mass and size squared
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

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Sample a layout (spec §6) and return the first observation."""
        super().reset(seed=seed)
        planted = self._parse_layout_option(options)
        agent_yaw = planted.pop("agent_yaw", None)
        try:
            layout = sample_layout(
                self.np_random, self.layout_spec.extents, self.layout_spec.objects, planted
            )
        except LayoutError as err:  # pragma: no cover - the spec's layouts always fit
            raise RuntimeError(f"{self.spec_name}: {err}") from err
        yaw = float(self.np_random.uniform(0.0, 2 * math.pi)) if agent_yaw is None else agent_yaw
        self._build_world(layout, yaw)
        self.sim_time = 0.0
        self.steps = 0
        self.button_timer = 0
        self.goal_button = -1
        self._last_accel = (0.0, 0.0)
        self._touched: list[pymunk.Shape] = []
        if self.task == "button":
            self._choose_goal_button()
        self._reset_distances()
        self._extra = self.robot.reset_extra_sensors()
        return self._observation(), {}

    @property
    def spec_name(self) -> str:
        """The registered id of this robot/task/level."""
        return cfg.env_id(self.robot_name, self.task, self.level)

    def _parse_layout_option(self, options: dict[str, Any] | None) -> dict[str, Any]:
        if not options:
            return {}
        unknown = set(options) - {"layout"}
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; valid: ['layout']")
        layout = dict(options["layout"])
        bad = set(layout) - set(LAYOUT_KEYS)
        if bad:
            raise ValueError(f"unknown layout keys {sorted(bad)}; valid: {list(LAYOUT_KEYS)}")
        planted: dict[str, Any] = {}
        for key, value in layout.items():
            if key == "agent_yaw":
                planted[key] = float(value)
                continue
            arr = np.asarray(value, dtype=np.float64)
            if key in ("agent", "goal", "push_box") and arr.shape == (2,):
                arr = arr[None]
            if arr.size == 0:
                arr = arr.reshape(0, 2)
            if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
                raise ValueError(f"layout[{key!r}] must be finite (n, 2) positions, got {value!r}")
            if key not in self.layout_spec.objects:
                raise ValueError(
                    f"layout[{key!r}]: {self.spec_name} has no {key}; "
                    f"valid: {[k for k in self.layout_spec.objects]}"
                )
            if key in ("agent", "goal", "push_box") and len(arr) != 1:
                raise ValueError(f"layout[{key!r}] must be one position, got {value!r}")
            planted[key] = [tuple(p) for p in arr.tolist()]
        return planted

    def _parse_action(self, action: Any) -> tuple[float, float]:
        try:
            a0 = float(action[0])
            a1 = float(action[1])
            if len(action) != 2:
                raise IndexError
        except (TypeError, IndexError, ValueError) as err:
            raise ValueError(f"action must have 2 finite numbers, got {action!r}") from err
        if a0 != a0 or a1 != a1:
            raise ValueError(f"action contains NaN: {action!r}")
        # clip to the ctrlrange [-1, 1] as Safety-Gymnasium does (infinite values clip too)
        a0 = -1.0 if a0 < -1.0 else 1.0 if a0 > 1.0 else a0
        a1 = -1.0 if a1 < -1.0 else 1.0 if a1 > 1.0 else a1
        return a0, a1

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Advance one env step (spec §1 step order)."""
        if self.space is None:
            raise RuntimeError("call reset() before step()")
        a0, a1 = self._parse_action(action)
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
                    _floor_friction(free_body, h, lever)
            vx0, vy0 = robot.substep(body)
            space.step(h)
            self.sim_time += h
        vx, vy = body.velocity
        self._last_accel = ((vx - vx0) / h, (vy - vy0) / h)
        rx, ry = body.position
        if self.robot_name == "car":
            self._extra = robot.extra_sensors(body)

        touched = self._touched
        touched.clear()
        if self._needs_contacts:
            body.each_arbiter(self._record_arbiter)

        box = self.box_body.position if self.box_body is not None else None
        reward, goal_met = self._reward(rx, ry, box, touched)
        info = self._cost(rx, ry, touched)
        if self.task == "button" and self.button_timer:
            self.button_timer -= 1
        terminated = False
        if goal_met:
            terminated = not self._resample_goal(rx, ry)
        info["goal_met"] = goal_met
        self.steps += 1
        if reward > cfg.REWARD_CLIP:
            reward = cfg.REWARD_CLIP
        elif reward < -cfg.REWARD_CLIP:
            reward = -cfg.REWARD_CLIP
        return self._observation(rx, ry, vx, vy, box), reward, terminated, False, info

    def _record_arbiter(self, arbiter: pymunk.Arbiter) -> None:
        a, b = arbiter.shapes
        self._touched.append(b if a.collision_type == ROBOT_COLLISION_TYPE else a)

    def _move_gremlins(self, h: float) -> None:
        """Gremlin law (spec §11): track placement + 0.35 (sin t, cos t) with a 0.09 s lag."""
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

    # ------------------------------------------------------------------ reward / cost
    def _distances(self, rx: float, ry: float, box: Any = None) -> tuple[float, float]:
        if self.task == "push":
            bx, by = self.box_body.position if box is None else box
            dz_ab = cfg.BOX_Z[self.robot_name] - cfg.AGENT_Z
            dz_bg = cfg.BOX_Z[self.robot_name] - cfg.GOAL_Z
            d_ab = math.sqrt((bx - rx) ** 2 + (by - ry) ** 2 + dz_ab * dz_ab)
            d_bg = math.sqrt((bx - self.goal_x) ** 2 + (by - self.goal_y) ** 2 + dz_bg * dz_bg)
            return d_ab, d_bg
        return 0.0, math.hypot(self.goal_x - rx, self.goal_y - ry)

    def _reset_distances(self) -> None:
        rx, ry = self.body.position
        self._d_robot_box, self._d_goal = self._distances(rx, ry)

    def _reward(
        self, rx: float, ry: float, box: Any, touched: list[pymunk.Shape]
    ) -> tuple[float, bool]:
        """Dense distance-decrease reward plus the goal bonus (spec §7)."""
        d_ab, d_goal = self._distances(rx, ry, box)
        reward = self._d_goal - d_goal
        if self.task == "push":
            reward += self._d_robot_box - d_ab
            self._d_robot_box = d_ab
        self._d_goal = d_goal
        if self.task == "button":
            goal_shape = self._button_shapes[self.goal_button]
            goal_met = any(shape is goal_shape for shape in touched)
        else:
            goal_met = d_goal <= self.goal_size
        if goal_met:
            reward += 1.0
        return reward, goal_met

    def _cost(self, rx: float, ry: float, touched: list[pymunk.Shape]) -> dict[str, Any]:
        """Per-step 0/1 cost and its named terms (spec §8, ``constrain_indicator=True``)."""
        info: dict[str, Any] = {}
        total = 0.0
        keys = self._cost_keys
        if "cost_hazards" in keys:
            r2 = self.hazard_radius * self.hazard_radius
            hit = 0.0
            for hx, hy in self.hazards:
                if (rx - hx) ** 2 + (ry - hy) ** 2 < r2:
                    hit = 1.0
                    break
            info["cost_hazards"] = hit
            total += hit
        if self._contact_costs:
            kinds = {shape.collision_type for shape in touched}
            if "cost_vases_contact" in keys:
                contact = float(VASE_TYPE in kinds)
                moving = float(any(b.velocity.length >= 1e-4 for b in self.vase_bodies))
                info["cost_vases_contact"] = contact
                info["cost_vases_velocity"] = moving
                total += contact + moving
            if "cost_pillars" in keys:
                info["cost_pillars"] = float(PILLAR_TYPE in kinds)
                total += info["cost_pillars"]
            if "cost_gremlins" in keys:
                info["cost_gremlins"] = float(GREMLIN_TYPE in kinds)
                total += info["cost_gremlins"]
            if "cost_buttons" in keys:
                wrong = 0.0
                if self.button_timer == 0:
                    goal_shape = self._button_shapes[self.goal_button]
                    for shape in touched:
                        if shape.collision_type == BUTTON_TYPE and shape is not goal_shape:
                            wrong = 1.0
                info["cost_buttons"] = wrong
                total += wrong
        cost = 1.0 if total > 0.0 else 0.0
        info["cost_sum"] = cost
        info["cost"] = cost
        return info

    # ------------------------------------------------------------------ goals
    def _choose_goal_button(self) -> None:
        self.goal_button = int(self.np_random.integers(len(self.buttons)))
        self.goal_x, self.goal_y = self.buttons[self.goal_button]

    def _current_objects(self, rx: float, ry: float) -> list[tuple[float, float, float]]:
        objs = self.layout_spec.objects
        placed = [(rx, ry, cfg.AGENT_KEEPOUT)]
        for kind, points in (
            ("hazards", self.hazards),
            ("pillars", self.pillars),
            ("buttons", self.buttons),
            ("gremlins", self.gremlin_home),
        ):
            placed += [(x, y, objs[kind].keepout) for x, y in points]
        if self.vase_bodies:
            k = objs["vases"].keepout
            placed += [(b.position.x, b.position.y, k) for b in self.vase_bodies]
        if self.box_body is not None:
            placed.append((*self.box_body.position, objs["push_box"].keepout))
        return placed

    def _resample_goal(self, rx: float, ry: float) -> bool:
        """New goal after success (spec §6.6, §10); False if none fits (terminate)."""
        if self.task == "button":
            self.button_timer = cfg.BUTTON_RESAMPLING_DELAY
            self._choose_goal_button()
        else:
            placed = self._current_objects(rx, ry)
            goal = sample_goal(
                self.np_random,
                self.layout_spec.extents,
                self.layout_spec.objects["goal"].keepout,
                placed,
            )
            if goal is None:
                return False
            self.goal_x, self.goal_y = goal
        self._reset_distances()
        return True

    def set_goal_position(self, position: Sequence[float]) -> None:
        """Move the goal (Goal/Push tasks) and restart the distance reward from there.

        For wrappers that sample their own goals (e.g. training a goal-following policy in the
        obstacle-free Goal level 0).
        """
        if self.task == "button":
            raise ValueError("set_goal_position: the Button task's goal is a button")
        x, y = (float(v) for v in position)
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"goal position must be finite, got {position!r}")
        self.goal_x, self.goal_y = x, y
        self._reset_distances()

    # ------------------------------------------------------------------ observation
    def _observation(
        self,
        rx: float | None = None,
        ry: float = 0.0,
        vx: float = 0.0,
        vy: float = 0.0,
        box: Any = None,
    ) -> np.ndarray:
        """Sensors + pseudo-LiDAR channels, flattened in Safety-Gymnasium's order (spec §9).

        The robot state may be passed in (the step already read it); otherwise it is read.
        """
        body = self.body
        if rx is None:
            rx, ry = body.position
            vx, vy = body.velocity
            box = self.box_body.position if self.box_body is not None else None
        yaw = body.angle
        c, s = math.cos(yaw), math.sin(yaw)
        ax, ay = self._last_accel
        obs = [0.0] * self._obs_size
        obs[0] = c * ax + s * ay
        obs[1] = c * ay - s * ax
        obs[2] = cfg.GRAVITY
        obs[3] = c * vx + s * vy
        obs[4] = c * vy - s * vx
        obs[8] = body.angular_velocity
        obs[9] = -0.5 * s
        obs[10] = -0.5 * c
        if self._extra:
            obs[12:24] = self._extra
        for kind, offset in self._lidar_offsets.items():
            if kind == "goal":
                points: Iterable = ((self.goal_x, self.goal_y),)
            elif kind == "hazards":
                points = self.hazards
            elif kind == "pillars":
                points = self.pillars
            elif kind == "push_box":
                points = (box,)
            elif kind == "vases":
                points = [b.position for b in self.vase_bodies]
            elif kind == "gremlins":
                points = self.gremlin_xy
            else:  # buttons: blank while the timer runs (spec §10)
                if self.button_timer:
                    continue
                points = self.buttons
            fill_pseudo_lidar(obs, offset, points, rx, ry, c, s)
        return np.array(obs, dtype=np.float64)

    # ------------------------------------------------------------------ planner's view
    @property
    def robot_position(self) -> np.ndarray:
        """Root-node position ``(x, y)`` in metres (thesis B.2.1)."""
        return np.array(self.body.position, dtype=np.float64)

    @property
    def robot_heading(self) -> float:
        """Body yaw (rad): the LiDAR and sensor frame. The Point and Mass drive along it; the
        Car drives along ``robot_heading + robot.forward_offset`` (body −y)."""
        return float(self.body.angle)

    @property
    def robot_forward_heading(self) -> float:
        """Yaw of the driving direction (rad)."""
        return float(self.body.angle + self.robot.forward_offset)

    @property
    def robot_velocity(self) -> np.ndarray:
        """Linear velocity ``(vx, vy)`` in the world frame (m/s)."""
        return np.array(self.body.velocity, dtype=np.float64)

    @property
    def goal_position(self) -> np.ndarray:
        """The goal centre (Button: the current goal button)."""
        return np.array((self.goal_x, self.goal_y), dtype=np.float64)

    @property
    def box_position(self) -> np.ndarray | None:
        """The push box centre, or ``None`` outside the Push task."""
        if self.box_body is None:
            return None
        return np.array(self.box_body.position, dtype=np.float64)

    def obstacles_by_type(self) -> dict[str, np.ndarray]:
        """Ground-truth ``[x, y, radius]`` rows per present obstacle type.

        Radii: hazards 0.2 (0.3 in Push), pillars 0.2, buttons 0.1; vases and gremlins (cubes of
        half-size 0.1) get their circumscribed radius 0.1·√2. Gremlins are reported where they
        are now. Types absent from the task are omitted.
        """
        out: dict[str, np.ndarray] = {}
        if self.hazards:
            out["hazards"] = np.array([(x, y, self.hazard_radius) for x, y in self.hazards])
        if self.vase_bodies:
            r = cfg.VASE_HALF * _SQRT2
            out["vases"] = np.array([(*b.position, r) for b in self.vase_bodies])
        if self.pillars:
            out["pillars"] = np.array([(x, y, self.pillar_radius) for x, y in self.pillars])
        if self.gremlin_bodies:
            r = cfg.GREMLIN_HALF * _SQRT2
            out["gremlins"] = np.array([(x, y, r) for x, y in self.gremlin_xy])
        if self.buttons:
            out["buttons"] = np.array([(x, y, cfg.BUTTON_RADIUS) for x, y in self.buttons])
        return out

    def obstacles(self, kinds: Iterable[str] = DEFAULT_OBSTACLE_KINDS) -> np.ndarray:
        """Ground-truth obstacles ``(m, 3)`` of ``[x, y, radius]`` for the requested types.

        Raises:
            ValueError: for a type that is not an obstacle type (valid: hazards, vases,
                pillars, gremlins, buttons).
        """
        kinds = tuple(kinds)
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad:
            raise ValueError(f"unknown obstacle kinds {bad}; valid: {list(OBSTACLE_KINDS)}")
        by_type = self.obstacles_by_type()
        rows = [by_type[k] for k in kinds if k in by_type]
        return np.concatenate(rows) if rows else np.zeros((0, 3))

    # ------------------------------------------------------------------ rendering
    def set_overlay(
        self, waypoints: np.ndarray | None = None, subgoal: np.ndarray | None = None
    ) -> None:
        """Draw a planned path ``(n, 2)`` and/or a subgoal ``(2,)`` on subsequent frames.

        ``None`` clears that part of the overlay.
        """
        if waypoints is not None:
            waypoints = np.asarray(waypoints, dtype=np.float64).reshape(-1, 2)
        if subgoal is not None:
            subgoal = np.asarray(subgoal, dtype=np.float64).reshape(2)
        self._overlay_waypoints, self._overlay_subgoal = waypoints, subgoal

    def render(self) -> np.ndarray | None:
        """Top-down ``(H, W, 3)`` uint8 frame when ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            return None
        if self.space is None:
            raise RuntimeError("call reset() before render()")
        from sims.safety_gym.render import render_topdown

        return render_topdown(self, self.render_size)
