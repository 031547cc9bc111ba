"""The Safety-Embedded MDP as a gymnasium wrapper (thesis §3.5.1, Alg. 2; docs/design.md)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.embedded.follower import Follower, PolicyFollower, default_follower
from semdp.embedded.perception import (
    GREMLIN_MODELS,
    OBSTACLE_KINDS,
    PERCEPTION_MODES,
    ButtonMemory,
    perceive_obstacles,
)
from semdp.embedded.shield import SafetyShield
from semdp.embedded.tracking import ego_to_world, select_tracking_index
from solvers.planner import SafeTrajectoryPlanner

#: Timing counters kept by :class:`SafetyEmbeddedEnv` (seconds, summed over its lifetime).
TIMING_KEYS: tuple[str, ...] = ("perception_s", "plan_s", "follow_s", "sim_s")


@dataclass
class Window:
    """One high-level step in progress (Alg. 2: a plan followed for up to k low-level steps)."""

    plan: Any
    waypoints: np.ndarray
    subgoal: np.ndarray
    n_obstacles: int
    obs: np.ndarray
    perception_s: float = 0.0
    plan_s: float = 0.0
    follow_s: float = 0.0
    sim_s: float = 0.0
    index: int = 0
    steps: int = 0
    reward: float = 0.0
    cost: float = 0.0
    goal_met: bool = False
    terminated: bool = False
    truncated: bool = False
    info: dict[str, Any] = field(default_factory=dict)
    cost_terms: dict[str, float] = field(default_factory=dict)
    shield_interventions: int = 0


@dataclass(frozen=True)
class LowLevelRecord:
    """One low-level step, as a set :attr:`SafetyEmbeddedEnv.recorder` receives it right after
    the inner env stepped (:mod:`semdp.evaluation.cost_trace`).

    Attributes:
        env: the SEMDP env.
        window: its window, updated by the step (``info``, ``obs``, ``plan``); it keeps changing.
        action: the low-level action sent to the robot (after the safety filter, if any).
        step: the env's lifetime low-level step count, this step included.
    """

    env: SafetyEmbeddedEnv
    window: Window
    action: Any
    step: int


class SafetyEmbeddedEnv(gym.Wrapper):
    """Subgoal action space over a Safety Gym replica env (Alg. 2).

    One step of this env: the action ``a`` in [-1, 1]^2 becomes the subgoal
    ``p + R(theta) (subgoal_scale * a)`` in the robot's ego frame (+-2 m by default); the planner
    plans a safe trajectory from the robot root ``p`` to it around the perceived obstacles
    (Eq. 3.3); the follower tracks it for ``k`` low-level steps (App. B.2.2). The reward is the
    sum of the ``k`` inner rewards (the SEMDP reward r'); the inner costs are summed into
    ``info["cost"]`` for logging only -- the high level is trained on reward, safety is the
    planner's job (§3.5.1).

    Episode ends and goal resampling inside the window (documented difference from the thesis'
    code, which drops such transitions from its replay buffer and never bootstraps them): the
    window stops at the inner step that terminated or truncated and the wrapper returns that
    step's flags, so our SAC stores the transition and bootstraps a time-out as for any env. The
    replica's 1000-step episodes are a multiple of k = 10, so a time-out always falls on a window
    boundary. A goal met inside the window (the inner env places a new goal and goes on) keeps
    the window running; the goal bonus is part of the summed reward and ``info["goal_met"]`` is
    set. Dropping those transitions would drop most of the reward signal at the laptop budget.

    ``info`` carries the plan and its certificate: ``plan`` (the planner's result),
    ``plan_feasible``, ``plan_fallback``, ``plan_escape``, ``plan_rescued``,
    ``plan_min_clearance``, ``subgoal``, ``n_obstacles``, the step's timings ``perception_s``,
    ``plan_s``, ``follow_s``, ``sim_s`` and ``low_level_steps``. The lifetime sums of the
    timings are in :attr:`timing`.

    Args:
        env: a ``sims`` Safety Gym env (any wrappers; the unwrapped env provides the pose,
            obstacle and LiDAR accessors).
        planner: the planner (``plan(start, subgoal, obstacles, warm_start=...)`` returning a
            result with ``waypoints`` and its certificate); None = the thesis' training setting,
            :class:`~solvers.planner.SafeTrajectoryPlanner` with fixed-lambda LM. Each wrapper
            needs its own planner (it keeps the receding-horizon warm start): the env factory
            (:func:`semdp.envs.make_env`) instantiates the config's planner node once per
            sub-env.
        follower: a :class:`Follower`; None = the committed follower of the env's robot (SAC
            weights for Point and Car, the P-controller for Mass; ``conf/robot/<name>.yaml``
            names the same ones).
        k: low-level steps per high-level step (thesis: 10).
        subgoal_scale: metres per unit action in the ego frame (thesis code: 2.0).
        d_min: tracking-point look-ahead (App. B.2.2: 0.2 m; the configs take the robot's
            ``lookahead``, 0.4 m for the Point: docs/semdp.md, "Followers").
        perception: ``"lidar"`` (default, reconstructed from the LiDAR bins),
            ``"lidar_refined"`` (bearings from the bins' aliasing) or ``"gt"``
            (:data:`semdp.embedded.perception.PERCEPTION_MODES`).
        obstacle_kinds: object types the planner avoids (buttons: all but the goal button;
            gremlins: the discs of their orbits; :mod:`semdp.embedded.perception`).
        brake_steps: the last ``brake_steps`` low-level steps of each window track the robot's
            current position (the follower brakes), so each window ends slow; 0 = off (thesis).
        draw_plan: pass the plan and subgoal to the env's renderer overlay.
        frame_every: with ``render_mode="rgb_array"``, record a frame every this many low-level
            steps into :attr:`frames` (0 = off); used for the evaluation GIF.
        shield: a last-line filter on every low-level action
            (:class:`~semdp.embedded.shield.SafetyShield`: one step then braking must stay out of
            every cost region, else brake or escape); None = the thesis' plain follower.
            ``info["shield_interventions"]`` counts the window's replaced actions.
        gremlins: how the planner sees a gremlin
            (:data:`~semdp.embedded.perception.GREMLIN_MODELS`): ``"moving"`` (the default:
            where it is now, for a filter with ``gremlins="moving"``) or ``"orbit"`` (the disc
            of its orbit).

    A :attr:`recorder`, when set, is given a :class:`LowLevelRecord` of every low-level step.
    """

    #: Given a :class:`LowLevelRecord` after every low-level step when set (diagnostics:
    #: :mod:`semdp.evaluation.cost_trace`); None records nothing. Class-level, so that envs
    #: unpickled from a checkpoint have it too.
    recorder: Callable[[LowLevelRecord], None] | None = None
    #: The planner's memory of the buttons LiDAR channel, made on first use (None until then).
    _buttons: ButtonMemory | None

    def __init__(
        self,
        env: gym.Env,
        planner: Any = None,
        follower: Follower | None = None,
        k: int = 10,
        subgoal_scale: float = 2.0,
        d_min: float = 0.2,
        perception: str = "lidar",
        obstacle_kinds: tuple[str, ...] | list[str] = OBSTACLE_KINDS,
        brake_steps: int = 0,
        draw_plan: bool = True,
        frame_every: int = 0,
        shield: SafetyShield | None = None,
        gremlins: str = "moving",
    ) -> None:
        super().__init__(env)
        if k < 1:
            raise ValueError(f"k (low-level steps per subgoal) must be >= 1, got {k}")
        if not subgoal_scale > 0:
            raise ValueError(f"subgoal_scale must be > 0, got {subgoal_scale}")
        if perception not in PERCEPTION_MODES:
            raise ValueError(f"perception must be one of {PERCEPTION_MODES}, got {perception!r}")
        if not 0 <= brake_steps < k:
            raise ValueError(f"brake_steps must be in [0, k={k}), got {brake_steps}")
        if frame_every < 0:
            raise ValueError(f"frame_every must be >= 0, got {frame_every}")
        if gremlins not in GREMLIN_MODELS:
            raise ValueError(f"gremlins must be one of {GREMLIN_MODELS}, got {gremlins!r}")
        base = env.unwrapped
        for attr in ("robot_position", "robot_heading", "obstacles", "obs_slices"):
            if not hasattr(type(base), attr) and not hasattr(base, attr):
                raise ValueError(
                    f"SafetyEmbeddedEnv needs a sims Safety Gym env (missing {attr!r}); "
                    f"got {base!r}"
                )
        if planner is None:
            planner = SafeTrajectoryPlanner(backend="lm")
        if not callable(getattr(planner, "plan", None)):
            raise ValueError(f"planner must have a plan() method, got {planner!r}")
        if follower is None:
            follower = default_follower(getattr(base, "robot_name", ""))
        if not callable(getattr(follower, "act", None)):
            raise ValueError(f"follower must have an act() method, got {follower!r}")
        self.planner = planner
        self._buttons = None
        self.follower: Follower = follower
        self.k = int(k)
        self.subgoal_scale = float(subgoal_scale)
        self.d_min = float(d_min)
        self.perception = perception
        self.obstacle_kinds = tuple(obstacle_kinds)
        self.gremlins = gremlins
        self.brake_steps = int(brake_steps)
        self.draw_plan = draw_plan
        self.frame_every = int(frame_every)
        self.shield = shield
        self.frames: list[np.ndarray] = []
        self.timing: dict[str, float] = dict.fromkeys(TIMING_KEYS, 0.0)
        self.high_level_steps = 0
        self.low_level_steps = 0
        #: Counts and timings of this env's copies in evaluation helper processes.
        self.elsewhere: dict[str, float] = {}
        if isinstance(self.follower, PolicyFollower):
            self.follower.bind(base.obs_slices)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._obs: np.ndarray | None = None
        self._fresh = True

    def counters(self) -> dict[str, float]:
        """The lifetime step counts and :attr:`timing` (an evaluation helper process reports
        its share with these; :mod:`semdp.common.vector_episodes`)."""
        return {**self.timing, "high_level_steps": float(self.high_level_steps),
                "low_level_steps": float(self.low_level_steps)}

    def add_counters(self, delta: dict[str, float]) -> None:
        """Record counts and timings measured by a copy of this env in another process, in
        :attr:`elsewhere` (they overlapped this process's wall time, so the time split leaves
        them out; step counts and the mean plan time include them)."""
        for key, value in delta.items():
            self.elsewhere[key] = self.elsewhere.get(key, 0.0) + float(value)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset the inner env and remember its observation for perception."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._obs = obs
        self._fresh = True  # no warm start from the previous episode's plan
        self.button_memory.forget()
        if self.shield is not None:
            self.shield.new_episode()
        self._record_frame()
        return obs, info

    @property
    def button_memory(self) -> ButtonMemory:
        """The planner's memory of the buttons LiDAR channel (Button tasks; forgotten at every
        reset)."""
        if self._buttons is None:
            self._buttons = ButtonMemory()
        return self._buttons

    def perceive(self, obs: np.ndarray) -> np.ndarray:
        """The planner's obstacles ``(m, 3)`` for observation ``obs`` (Eq. 3.3's set): the
        perceived objects of :attr:`obstacle_kinds` (a gremlin: the disc of its orbit, or
        where it is now: :attr:`gremlins`)."""
        return perceive_obstacles(self.env.unwrapped, obs, self.perception, self.obstacle_kinds,
                                  memory=self.button_memory, gremlins=self.gremlins)

    def _record_frame(self) -> None:
        if self.frame_every and getattr(self.env.unwrapped, "render_mode", None) == "rgb_array":
            self.frames.append(self.env.unwrapped.render())

    def subgoal_of(self, action: np.ndarray) -> np.ndarray:
        """World-frame subgoal for a high-level action (ego frame, +-subgoal_scale metres)."""
        base = self.env.unwrapped
        offset = ego_to_world(self.subgoal_scale * np.asarray(action, float), base.robot_heading)
        return np.asarray(base.robot_position, dtype=np.float64) + offset

    def step(self, action):
        """Plan to the subgoal, follow the plan for k steps, return the summed reward."""
        window = self.begin_window(action)
        for _ in range(self.k):
            t0 = time.perf_counter()
            obs, position, heading, target = self.tracking_target(window)
            low_action = self.follower.act(obs, position, heading, target)
            window.follow_s += time.perf_counter() - t0
            if self.low_level_step(window, low_action):
                break
        return self.end_window(window)

    # ------------------------------------------------------------ the window, phase by phase
    # ``step`` = ``begin_window`` + k x (``tracking_target``, follower, ``low_level_step``) +
    # ``end_window``. :class:`semdp.embedded.vector.LockstepVectorEnv` calls the same phases for
    # several envs in lockstep, so that their followers act in one batched forward.

    def begin_window(self, action) -> Window:
        """Perceive, turn the action into a subgoal and plan (Alg. 2: subgoal, Eq. 3.3 plan)."""
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != (2,) or not np.all(np.isfinite(action)):
            raise ValueError(f"SEMDP action must be 2 finite numbers, got {action!r}")
        action = np.clip(action, -1.0, 1.0)
        base = self.env.unwrapped

        t0 = time.perf_counter()
        start = np.asarray(base.robot_position, dtype=np.float64).copy()
        subgoal = self.subgoal_of(action)
        obstacles = self.perceive(self._obs)
        t1 = time.perf_counter()
        plan = self.planner.plan(start, subgoal, obstacles, warm_start=not self._fresh)
        t2 = time.perf_counter()
        self._fresh = False
        waypoints = np.asarray(plan.waypoints)
        if self.draw_plan and hasattr(base, "set_overlay"):
            base.set_overlay(waypoints=waypoints, subgoal=subgoal)
        return Window(plan=plan, waypoints=waypoints, subgoal=subgoal,
                      n_obstacles=len(obstacles), obs=self._obs,
                      perception_s=t1 - t0, plan_s=t2 - t1)

    def tracking_target(self, window: Window) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """The follower's inputs for the next low-level step: ``(obs, position, heading,
        target)``, the target being the tracking point of App. B.2.2 (the robot's own position
        in the last ``brake_steps`` steps)."""
        base = self.env.unwrapped
        position = base.robot_position
        if window.steps >= self.k - self.brake_steps:
            target = position
        else:
            window.index = select_tracking_index(window.waypoints, position, window.index,
                                                 self.d_min)
            target = window.waypoints[window.index]
        return window.obs, position, base.robot_heading, target

    def low_level_step(self, window: Window, low_action) -> bool:
        """Execute one low-level action in the inner env; True when the window is over.

        The one place where a low-level action is finalised and sent to the robot, for the
        sequential :meth:`step` and the batched :class:`~semdp.embedded.vector.LockstepVectorEnv`
        alike: a low-level safety filter that replaces the follower's action belongs here, just
        before ``self.env.step``.
        """
        if self.shield is not None:
            t0 = time.perf_counter()
            safe = self.shield.filter(low_action, self.env.unwrapped, window.obs)
            window.shield_interventions += safe is not low_action
            low_action = safe
            window.follow_s += time.perf_counter() - t0
        t0 = time.perf_counter()
        obs, reward, terminated, truncated, info = self.env.step(low_action)
        window.sim_s += time.perf_counter() - t0
        window.steps += 1
        window.obs, window.terminated, window.truncated, window.info = (
            obs, terminated, truncated, info)
        window.reward += float(reward)
        window.cost += float(info.get("cost", 0.0))
        for key, value in info.items():
            if key.startswith("cost_"):
                window.cost_terms[key] = window.cost_terms.get(key, 0.0) + float(value)
        window.goal_met = window.goal_met or bool(info.get("goal_met", False))
        if self.frame_every and (self.low_level_steps + window.steps) % self.frame_every == 0:
            self._record_frame()
        if self.recorder is not None:
            self.recorder(LowLevelRecord(self, window, low_action,
                                         self.low_level_steps + window.steps))
        return bool(terminated or truncated) or window.steps >= self.k

    def end_window(self, window: Window):
        """Book the window and return the SEMDP step ``(obs, r', terminated, truncated, info)``."""
        self._obs = window.obs
        self.high_level_steps += 1
        self.low_level_steps += window.steps
        step_timing = {
            "perception_s": window.perception_s, "plan_s": window.plan_s,
            "follow_s": window.follow_s, "sim_s": window.sim_s,
        }
        for key, value in step_timing.items():
            self.timing[key] += value

        plan = window.plan
        out = {key: value for key, value in window.info.items() if not key.startswith("cost")}
        out.update(window.cost_terms)
        out.update(
            cost=window.cost,
            goal_met=window.goal_met,
            plan=plan,
            subgoal=window.subgoal,
            n_obstacles=window.n_obstacles,
            plan_feasible=bool(getattr(plan, "feasible", True)),
            plan_fallback=bool(getattr(plan, "fallback", False)),
            plan_escape=bool(getattr(plan, "escape_mode", False)),
            plan_rescued=bool(getattr(plan, "rescued", False)),
            plan_min_clearance=float(getattr(plan, "min_clearance", np.inf)),
            low_level_steps=window.steps,
            shield_interventions=window.shield_interventions,
            **step_timing,
        )
        return window.obs, window.reward, window.terminated, window.truncated, out
