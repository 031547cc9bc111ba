"""Export a trained SAC follower from a ``semdp-train`` run directory (thesis App. B.2.4).

    python -m semdp.evaluation.follower_export <run dir> semdp/embedded/weights/point.pt

Reads ``<run dir>/config.yaml`` (to rebuild the goal-reaching env and name its sensors) and the
actor of ``<run dir>/checkpoints/last.pt``; keeps only the mean head of the squashed Gaussian
policy (the follower acts with ``tanh(mean)``) and writes a small weights file that
:class:`semdp.embedded.follower.PolicyFollower` loads.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from semdp.common.checkpoint_files import load_checkpoint_file
from semdp.embedded.follower_weights import export_follower
from semdp.run_config import load_run_config


def actor_mean_state(actor_state: dict[str, Any], act_dim: int) -> tuple[dict[str, Any], list]:
    """The mean part of a :class:`SquashedGaussianActor` as a plain ``Sequential`` state dict.

    The SAC actor is ``net = Linear, ReLU, ..., Linear(2 act_dim)`` whose output is
    ``(mean, raw_log_std)``; the returned state holds the same hidden layers and the first
    ``act_dim`` rows of the head, indexed as in :func:`load_follower_actor`'s network.
    """
    linear = sorted(
        {int(key.split(".")[1]) for key in actor_state if key.startswith("net.")}
    )
    if not linear:
        raise ValueError(f"not a SquashedGaussianActor state dict: keys {sorted(actor_state)}")
    state: dict[str, Any] = {}
    hidden: list[int] = []
    for position, index in enumerate(linear):
        weight, bias = actor_state[f"net.{index}.weight"], actor_state[f"net.{index}.bias"]
        if index == linear[-1]:
            if weight.shape[0] != 2 * act_dim:
                raise ValueError(f"head has {weight.shape[0]} outputs, expected 2 x {act_dim}")
            weight, bias = weight[:act_dim], bias[:act_dim]
        else:
            hidden.append(int(weight.shape[0]))
        state[f"{2 * position}.weight"] = weight.clone()
        state[f"{2 * position}.bias"] = bias.clone()
    return state, hidden


def export_run(run_dir: str | Path, out: str | Path) -> Path:
    """Write the follower weights of a finished follower-training run to ``out``."""
    from hydra.utils import instantiate

    import semdp.envs  # noqa: F401  (registers the sims ids)

    run_dir = Path(run_dir)
    cfg = load_run_config(run_dir)
    ckpt = load_checkpoint_file(run_dir / "checkpoints" / "last.pt", map_location="cpu")
    import gymnasium as gym

    env = instantiate(cfg.env.wrapper)(gym.make(cfg.env.id))
    if not hasattr(env, "sensor_names"):
        raise ValueError(f"{run_dir} was not trained on a GoalReachingEnv (env {cfg.env.id})")
    act_dim = int(env.action_space.shape[0])
    algo_state = ckpt["algo"]
    extra: dict[str, Any] = {}
    if any(key.startswith("mean_net.") for key in algo_state["actor"]):
        # on-policy Gaussian actor (the PPO-Lag low level of "SAC + PPO Lag"): mean net,
        # observation normaliser, clipped (not squashed) mean action
        state = {key.removeprefix("mean_net."): value for key, value in algo_state["actor"].items()
                 if key.startswith("mean_net.")}
        hidden = [int(v.shape[0]) for k, v in state.items() if k.endswith(".weight")][:-1]
        norm = algo_state["normalizer"]
        import numpy as np

        extra = {
            "activation": str(cfg.algo.get("activation", "tanh")), "output": "clip",
            "obs_mean": np.asarray(norm["mean"], dtype=np.float32),
            "obs_std": np.sqrt(np.asarray(norm["var"]) + 1e-8).astype(np.float32),
            "obs_clip": float(cfg.algo.get("obs_clip", 5.0)),
        }
    else:
        state, hidden = actor_mean_state(algo_state["actor"], act_dim)
    meta = {
        **extra,
        "obs_dim": int(env.observation_space.shape[0]),
        "act_dim": act_dim,
        "hidden_sizes": hidden,
        "sensor_slices": list(env.sensor_names),
        "env_id": str(cfg.env.id),
        "env_steps": int(ckpt["algo"]["env_steps"]),
    }
    return export_follower(state, meta, out)


def main(argv: list[str] | None = None) -> None:
    """CLI: ``python -m semdp.evaluation.follower_export RUN_DIR OUT``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", help="semdp-train run directory of a follower training run")
    parser.add_argument("out", help="weights file to write, e.g. semdp/embedded/weights/point.pt")
    args = parser.parse_args(argv)
    path = export_run(args.run_dir, args.out)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")


if __name__ == "__main__":
    main(sys.argv[1:])
