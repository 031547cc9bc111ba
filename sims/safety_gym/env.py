"""The Safety Gym replica environment: robot x task x level on a pymunk plane.

One job per module; this one is the gymnasium API that ties them together:
:mod:`~sims.safety_gym.world` (bodies, physics substeps, exact copies),
:mod:`~sims.safety_gym.rules` (reward, cost, goals), :mod:`~sims.safety_gym.observation`
(sensors and pseudo-LiDAR), :mod:`~sims.safety_gym.planner_view` (poses and obstacles for the
planner) and :mod:`~sims.safety_gym.overlay` (frames). Step order follows Safety-Gymnasium's
``builder.step``: clip the action, run the physics substeps (gremlins moved before each), reward,
cost, button-timer tick, goal check and resampling (the episode continues), observation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium
import numpy as np
import pymunk

from sims.safety_gym import config as cfg
from sims.safety_gym.layout import LayoutError, sample_layout
from sims.safety_gym.observation import SensorObservation
from sims.safety_gym.overlay import TopDownRendering
from sims.safety_gym.planner_view import PlannerView
from sims.safety_gym.robots import ROBOT_CLASSES, Robot
from sims.safety_gym.rules import TaskRules
from sims.safety_gym.world import PhysicsWorld

LAYOUT_KEYS: tuple[str, ...] = (
    "agent", "agent_yaw", "goal", "hazards", "vases", "pillars", "push_box", "buttons", "gremlins",
)  # fmt: skip


class SafetyGymEnv(
    PhysicsWorld, TaskRules, SensorObservation, PlannerView, TopDownRendering, gymnasium.Env
):
    """Safety Gym task for one robot at one level (docs/simulators.md, "What is replicated").

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
            variants; the defaults are Safety Gym's (``robot_scale`` 1.0).

    Reset options: ``{"layout": {...}}`` plants positions: ``"agent": (x, y)``,
    ``"agent_yaw": float`` and, per object type, a list of ``(x, y)`` (its length may differ
    from the level's count). Unplanted objects are sampled clear of the planted ones.

    ``step`` returns the gymnasium 5-tuple; ``info["cost"]`` is the 0/1 indicator, beside the
    named terms of the constrained objects (``cost_hazards``, ``cost_vases_contact``,
    ``cost_vases_velocity``, ``cost_pillars``, ``cost_gremlins``, ``cost_buttons``) and
    ``cost_sum`` (= ``cost``), plus ``goal_met``.
    """

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
        self._init_observation_space()
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

        Keepouts stay Safety Gym's; the box mass scales with its area (constant density).
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

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Sample a layout (Safety Gym's placement rules) and return the first observation."""
        super().reset(seed=seed)
        planted = self._parse_layout_option(options)
        agent_yaw = planted.pop("agent_yaw", None)
        try:
            layout = sample_layout(
                self.np_random, self.layout_spec.extents, self.layout_spec.objects, planted
            )
        except LayoutError as err:  # pragma: no cover - Safety Gym's layouts always fit
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
        """Advance one env step (Safety-Gymnasium's ``builder.step`` order)."""
        if self.space is None:
            raise RuntimeError("call reset() before step()")
        a0, a1 = self._parse_action(action)
        rx, ry, vx, vy = self._advance_physics(a0, a1)
        if self.robot_name == "car":
            self._extra = self.robot.extra_sensors(self.body)
        touched = self._collect_contacts()
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
