"""Measure a trajectory follower (thesis App. B.2.2, B.2.4).

    python -m semdp.evaluation.follower_eval --robot point --trials 200
    python -m semdp.evaluation.follower_eval --robot mass --trials 200      # P-controller

Two measurements on the ``sims`` Safety Gym replica:

* **reaching**: from a reset (optionally after a few random actions, so the robot starts
  moving), a goal is placed uniformly 0.2..0.4 m away in a random direction; success = the root
  comes within 0.05 m of it within 50 low-level steps (obstacle-free ``Goal0`` env).
* **tracking**: in the ``Goal1`` env (hazards + a vase), a 30-waypoint plan from the root to a
  random ego-frame subgoal (+-2 m) is computed with ground-truth obstacles; the follower tracks it
  with the App. B.2.2 tracking point until the root is within 0.05 m of the last waypoint (or a
  step limit). The cross-track error of a step is the distance from the root to the plan's
  polyline.
* **cruise speed**: on an obstacle-free straight line, the tracking point is kept ``lookahead``
  ahead of the root's progress along the line; the robot's median speed once it has settled.
  A follower trained to stop at its goal slows for a tracking point within its stopping
  distance, so this is what the look-ahead costs in pace (App. B.2.2 uses 0.2 m).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.embedded.follower import Follower, PolicyFollower, default_follower
from semdp.embedded.perception import perceive_obstacles
from semdp.embedded.tracking import ego_to_world, select_tracking_index

ROBOTS = ("point", "car", "mass")


def point_to_polyline_distance(point: np.ndarray, polyline: np.ndarray) -> float:
    """Euclidean distance from ``point`` (2,) to the polyline through ``polyline`` (N, 2)."""
    if len(polyline) == 1:
        return float(np.hypot(*(point - polyline[0])))
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    length_sq = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", point - a, ab) / np.maximum(length_sq, 1e-18), 0.0, 1.0)
    nearest = a + t[:, None] * ab
    return float(np.min(np.hypot(*(point - nearest).T)))


@dataclass
class ReachingStats:
    """Outcome of :func:`evaluate_reaching`."""

    trials: int
    success_rate: float
    mean_steps_to_success: float
    warmup_steps: int


@dataclass
class TrackingStats:
    """Outcome of :func:`evaluate_tracking` (metres, low-level steps)."""

    trials: int
    mean_cross_track: float
    p95_cross_track: float
    max_cross_track: float
    mean_cross_track_first_k: float
    end_reached_rate: float
    mean_steps: float


def _trial_env(follower: Follower, env_id: str, trials: int, seed: int
               ) -> tuple[gym.Env, Any, np.random.Generator]:
    """The env of a measurement, its unwrapped base (the follower bound to its sensors) and the
    generator of the trials' goals."""
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    env = gym.make(env_id)
    if isinstance(follower, PolicyFollower):
        follower.bind(env.unwrapped.obs_slices)
    return env, env.unwrapped, np.random.default_rng(seed)


def evaluate_reaching(
    follower: Follower,
    env_id: str,
    trials: int = 200,
    max_steps: int = 50,
    radius: float = 0.05,
    distance_range: tuple[float, float] = (0.2, 0.4),
    warmup_steps: int = 0,
    seed: int = 0,
) -> ReachingStats:
    """Fraction of goals ``distance_range`` away reached within ``radius`` in ``max_steps``."""
    env, base, rng = _trial_env(follower, env_id, trials, seed)
    successes, steps_needed = 0, []
    for trial in range(trials):
        obs, _ = env.reset(seed=seed + trial)
        for _ in range(warmup_steps):
            obs, *_ = env.step(rng.uniform(-1.0, 1.0, size=2))
        angle = rng.uniform(-math.pi, math.pi)
        goal = base.robot_position + rng.uniform(*distance_range) * np.array(
            [math.cos(angle), math.sin(angle)]
        )
        for step in range(1, max_steps + 1):
            action = follower.act(obs, base.robot_position, base.robot_heading, goal)
            obs, *_ = env.step(action)
            if np.hypot(*(base.robot_position - goal)) < radius:
                successes += 1
                steps_needed.append(step)
                break
    env.close()
    return ReachingStats(
        trials=trials,
        success_rate=successes / trials,
        mean_steps_to_success=float(np.mean(steps_needed)) if steps_needed else math.nan,
        warmup_steps=warmup_steps,
    )


def evaluate_tracking(
    follower: Follower,
    env_id: str,
    planner,
    trials: int = 50,
    max_steps: int = 300,
    d_min: float = 0.2,
    k: int = 10,
    end_radius: float = 0.05,
    seed: int = 0,
) -> TrackingStats:
    """Cross-track error while tracking whole planned paths (ground-truth obstacles)."""
    env, base, rng = _trial_env(follower, env_id, trials, seed)
    errors, first_k, lengths, reached = [], [], [], 0
    for trial in range(trials):
        obs, _ = env.reset(seed=seed + trial)
        offset = ego_to_world(rng.uniform(-2.0, 2.0, size=2), base.robot_heading)
        subgoal = base.robot_position + offset
        obstacles = perceive_obstacles(base, obs, mode="gt")
        waypoints = np.asarray(planner.plan(base.robot_position, subgoal, obstacles).waypoints)
        index = 0
        for step in range(max_steps):
            index = select_tracking_index(waypoints, base.robot_position, index, d_min)
            action = follower.act(obs, base.robot_position, base.robot_heading, waypoints[index])
            obs, *_ = env.step(action)
            error = point_to_polyline_distance(base.robot_position, waypoints)
            errors.append(error)
            if step < k:
                first_k.append(error)
            if np.hypot(*(base.robot_position - waypoints[-1])) < end_radius:
                reached += 1
                break
        lengths.append(step + 1)
    env.close()
    errs = np.asarray(errors)
    return TrackingStats(
        trials=trials,
        mean_cross_track=float(errs.mean()),
        p95_cross_track=float(np.percentile(errs, 95)),
        max_cross_track=float(errs.max()),
        mean_cross_track_first_k=float(np.mean(first_k)),
        end_reached_rate=reached / trials,
        mean_steps=float(np.mean(lengths)),
    )


def cruise_speed(
    follower: Follower,
    env_id: str,
    lookahead: float,
    episodes: int = 3,
    steps: int = 100,
    settle: int = 30,
    seed: int = 0,
) -> float:
    """Median root speed (m/s) over steps ``settle..steps`` of ``episodes`` straight-line runs
    along the initial heading, the tracking point ``lookahead`` m ahead of the root's progress."""
    if not lookahead > 0:
        raise ValueError(f"lookahead must be > 0, got {lookahead}")
    if not 0 <= settle < steps:
        raise ValueError(f"need 0 <= settle < steps, got settle={settle}, steps={steps}")
    env, base, _ = _trial_env(follower, env_id, episodes, seed)
    speeds: list[float] = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        start = np.array(base.robot_position, dtype=np.float64)
        direction = np.array([math.cos(base.robot_heading), math.sin(base.robot_heading)])
        for step in range(steps):
            position = np.array(base.robot_position, dtype=np.float64)
            target = start + (float((position - start) @ direction) + lookahead) * direction
            obs, *_ = env.step(follower.act(obs, position, base.robot_heading, target))
            if step >= settle:
                speeds.append(float(np.hypot(*base.robot_velocity)))
    env.close()
    return float(np.median(speeds))


def main(argv: list[str] | None = None) -> None:
    """CLI: print (and optionally save) reaching and tracking figures of one robot's follower."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=ROBOTS, required=True)
    parser.add_argument("--weights", default=None, help="weights file (default: committed)")
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--tracking-trials", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--lookahead", type=float, default=0.2,
                        help="tracking-point look-ahead of the tracking measurement (m)")
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    args = parser.parse_args(argv)
    import semdp.envs  # noqa: F401  (registers the sims ids)
    from solvers.planner import SafeTrajectoryPlanner

    name = args.robot.capitalize()
    follower = default_follower(args.robot, args.weights)
    out = {}
    for warmup in (0, 10):
        stats = evaluate_reaching(
            follower, f"sims/Safety{name}Goal0-v0", args.trials, warmup_steps=warmup,
            seed=args.seed,
        )
        out[f"reaching_warmup{warmup}"] = asdict(stats)
        print(f"{name} reaching (0.2-0.4 m, 0.05 m, <= 50 steps, {warmup} random steps first): "
              f"{stats.success_rate:.1%} of {stats.trials}, "
              f"mean {stats.mean_steps_to_success:.1f} steps")
    planner = SafeTrajectoryPlanner(backend="ipopt")
    tracking = evaluate_tracking(
        follower, f"sims/Safety{name}Goal1-v0", planner, args.tracking_trials,
        d_min=args.lookahead, seed=args.seed,
    )
    out["tracking"] = asdict(tracking)
    print(f"{name} tracking (30-waypoint IPOPT plans, {tracking.trials} paths, look-ahead "
          f"{args.lookahead} m): cross-track "
          f"mean {tracking.mean_cross_track:.3f} m, first 10 steps "
          f"{tracking.mean_cross_track_first_k:.3f} m, p95 {tracking.p95_cross_track:.3f} m, "
          f"max {tracking.max_cross_track:.3f} m; end reached {tracking.end_reached_rate:.0%} "
          f"in {tracking.mean_steps:.0f} steps on average")
    for lookahead in (0.2, 0.3, 0.4, 0.6):
        speed = cruise_speed(follower, f"sims/Safety{name}Goal0-v0", lookahead, seed=args.seed)
        out[f"cruise_speed_{lookahead}"] = speed
        print(f"{name} cruise speed on a straight line, tracking point {lookahead} m ahead: "
              f"{speed:.2f} m/s")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])
