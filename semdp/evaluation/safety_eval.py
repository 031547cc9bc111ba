"""Evaluation-time safety of the SEMDP with a source for every violation (thesis §3.5.1).

    python -m semdp.evaluation.safety_eval --env semdp_point_push1 --episodes 50 \
        --run outputs/train/<semdp run dir>
    python -m semdp.evaluation.safety_eval --env semdp_mass_push1 --policy random \
        planner@env.eval_planner=lm env.perception=gt

The env is the evaluation env of the option ``env=<--env>`` (its ``eval_wrapper``), composed by
Hydra with the trailing overrides.

Runs ``episodes`` full episodes of :class:`SafetyEmbeddedEnv` with a trained SAC high level
(mean action, loaded from a run directory) or uniformly random subgoals, and attributes each
high-level window that incurred cost to one source, checked against the ground truth at the
start of the window:

* ``perception`` -- the plan keeps eps' from every perceived obstacle (certificate) but some
  waypoint is closer than eps' to a true obstacle (LiDAR reconstruction error or aliasing);
* ``planner`` -- the returned plan was a fallback / escape plan or failed its own certificate;
* ``discretisation`` -- every waypoint keeps eps' from the true obstacles but a segment between
  two waypoints does not;
* ``following`` -- the plan is safe against the true obstacles, segments included, and the
  robot still left it by more than the margin (tracking error, momentum at window ends, or the
  box pushing the robot).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from hydra.utils import instantiate
from omegaconf import OmegaConf

from semdp.common.checkpoint_files import load_checkpoint_file
from semdp.configs import compose_config
from semdp.embedded.perception import perceive_obstacles
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.evaluation.follower_eval import point_to_polyline_distance
from semdp.run_config import load_run_config


def _segment_distance(waypoints: np.ndarray, centre: np.ndarray) -> float:
    return point_to_polyline_distance(centre, waypoints)


def classify_window(plan: Any, true_obstacles: np.ndarray, clearance: float) -> str:
    """Source of a cost incurred while following ``plan`` (see the module docstring)."""
    if getattr(plan, "fallback", False) or getattr(plan, "escape_mode", False) or not getattr(
        plan, "feasible", True
    ):
        return "planner"
    waypoints = np.asarray(plan.waypoints)
    if len(true_obstacles):
        centres = true_obstacles[:, :2]
        gaps = np.linalg.norm(waypoints[:, None] - centres[None], axis=-1)
        if gaps.min() < clearance - 1e-6:
            return "perception"
        if min(_segment_distance(waypoints, c) for c in centres) < clearance - 1e-6:
            return "discretisation"
    return "following"


def load_sac_policy(run_dir: str | Path, stochastic: bool = False):
    """``obs -> action`` of the SAC actor saved in ``run_dir``: the mean action, or a sample as
    during training (``stochastic``)."""
    import torch

    from semdp.common.networks import SquashedGaussianActor

    run_dir = Path(run_dir)
    cfg = load_run_config(run_dir)
    state = load_checkpoint_file(run_dir / "checkpoints" / "last.pt",
                                 map_location="cpu")["algo"]["actor"]
    obs_dim = int(state["net.0.weight"].shape[1])
    actor = SquashedGaussianActor(obs_dim, 2, tuple(cfg.algo.hidden_sizes))
    actor.load_state_dict(state)
    actor.eval()

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            action, _ = actor(torch.as_tensor(obs, dtype=torch.float32)[None], not stochastic)
        return action[0].numpy()

    return policy


def evaluate_safety(
    env: SafetyEmbeddedEnv, policy, episodes: int, seed: int = 0
) -> dict[str, Any]:
    """Run ``episodes`` episodes; return cost/reward statistics and the violation sources."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    base = env.unwrapped
    clearance = float(getattr(env.planner, "clearance", 0.5))
    returns, costs, sources = [], [], Counter()
    plans = fallbacks = escapes = rescues = shielded = low_steps = 0
    violations: list[dict[str, Any]] = []
    tic = time.perf_counter()
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        ret = cost = 0.0
        while True:
            true_obstacles = perceive_obstacles(base, obs, "gt", env.obstacle_kinds,
                                                use_radii=True)
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            plan = info["plan"]
            plans += 1
            fallbacks += bool(info["plan_fallback"])
            escapes += bool(info["plan_escape"])
            rescues += bool(info.get("plan_rescued", False))
            shielded += int(info.get("shield_interventions", 0))
            low_steps += int(info.get("low_level_steps", 0))
            ret += reward
            if info["cost"] > 0:
                source = classify_window(plan, true_obstacles, clearance)
                sources[source] += 1
                cost += info["cost"]
                violations.append({"episode": episode, "source": source,
                                   "cost": float(info["cost"]),
                                   "min_clearance_perceived": info["plan_min_clearance"]})
            if terminated or truncated:
                break
        returns.append(ret)
        costs.append(cost)
    return {
        "episodes": episodes,
        "return_mean": float(np.mean(returns)),
        "return_std": float(np.std(returns)),
        "cost_mean": float(np.mean(costs)),
        "episodes_with_cost": int(np.sum(np.asarray(costs) > 0)),
        "cost_steps_total": float(np.sum(costs)),
        "violation_windows_by_source": dict(sources),
        "plans": plans,
        "fallback_rate": fallbacks / max(plans, 1),
        "escape_rate": escapes / max(plans, 1),
        "rescue_rate": rescues / max(plans, 1),
        "shield_rate": shielded / max(low_steps, 1),
        "high_level_steps_per_s": plans / max(time.perf_counter() - tic, 1e-9),
        "violations": violations[:50],
    }


def main(argv: list[str] | None = None) -> None:
    """CLI: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="semdp_point_push1", help="a conf/env SEMDP env")
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--run", default=None, help="SEMDP run dir (SAC high level)")
    parser.add_argument("--policy", default="sac", choices=("sac", "sac_sample", "random"),
                        help="sac: mean action; sac_sample: sampled as in training")
    parser.add_argument("--json", default=None)
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of the train config")
    args = parser.parse_args(argv)

    cfg = compose_config("train", [f"env={args.env}", *args.overrides])
    env_cfg = OmegaConf.to_container(cfg.env, resolve=True)
    assert isinstance(env_cfg, dict)
    if not isinstance(env_cfg.get("eval_wrapper"), dict):
        raise SystemExit(f"safety_eval: env={args.env} is not a Safety-Embedded MDP env")
    env = instantiate(env_cfg["eval_wrapper"])(gym.make(env_cfg["id"], **env_cfg["kwargs"]))
    if args.policy == "random" or args.run is None:
        rng = np.random.default_rng(args.seed)

        def policy(_obs: np.ndarray) -> np.ndarray:
            return rng.uniform(-1.0, 1.0, size=2)

        label = "random subgoals"
    else:
        policy = load_sac_policy(args.run, stochastic=args.policy == "sac_sample")
        label = f"{args.policy} from {args.run}"
    tic = time.perf_counter()
    out = evaluate_safety(env, policy, args.episodes, seed=args.seed)
    out["wall_time_s"] = time.perf_counter() - tic
    out.update(env_id=env_cfg["id"], env=args.env, overrides=args.overrides, policy=label,
               plan_ms_mean=1e3 * env.timing["plan_s"] / max(env.high_level_steps, 1))
    print(f"{env_cfg['id']} [{label}] {' '.join(args.overrides)}: return "
          f"{out['return_mean']:.2f} +- {out['return_std']:.2f}, cost {out['cost_mean']:.3f} "
          f"({out['episodes_with_cost']}/{out['episodes']} episodes with cost), violation "
          f"windows by source {out['violation_windows_by_source']}, fallback "
          f"{out['fallback_rate']:.1%}, escape {out['escape_rate']:.1%}, plan "
          f"{out['plan_ms_mean']:.1f} ms, wall {out['wall_time_s']:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])
