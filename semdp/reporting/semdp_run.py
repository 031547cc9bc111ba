"""Post-training artefacts of a SEMDP run (thesis §3.6): the time split, training
curves and a GIF of an evaluation episode with the plans drawn.

Used as the ``post_train`` hook of the ``semdp_*`` env configs (see :func:`after_training`); the
time split is read from the SEMDP envs' counters (:mod:`semdp.embedded.timing`).
"""

from __future__ import annotations

import csv
import functools
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from semdp.embedded.timing import find_semdp, timing_summary
from semdp.embedded.wrapper import TIMING_KEYS

logger = logging.getLogger(__name__)


def _epoch_split(progress_csv: Path | None) -> dict[str, float] | None:
    """The training wall time's split summed over the ``time_*`` columns of ``progress.csv``
    (:mod:`semdp.embedded.timing`), or None when the file or the columns are missing."""
    if progress_csv is None or not Path(progress_csv).is_file():
        return None
    with Path(progress_csv).open(newline="") as f:
        rows = list(csv.DictReader(f))
    keys = [*TIMING_KEYS, "learning_and_overhead_s"]
    if not rows or any(f"time_{key}" not in rows[0] for key in keys):
        return None
    return {key: sum(float(r[f"time_{key}"] or 0.0) for r in rows) for key in keys}


def throughput(algo: Any, progress_csv: Path | None = None) -> dict[str, Any]:
    """High-level and low-level steps/s of training and the wall-time split.

    The rates are training steps per second of training wall time (``algo.wall_time``, the
    periodic evaluations included). The split is the sum of ``progress.csv``'s per-epoch
    ``time_*`` columns when ``progress_csv`` has them; otherwise the time spent inside the
    training and evaluation SEMDP envs (the final evaluation too, which the training wall time
    does not include) and ``learning_and_overhead_s``, the rest of the training wall time.
    """
    train = timing_summary([algo.envs])
    evaluation = timing_summary([algo.eval_envs])  # this process's share: the wall time's
    work = timing_summary([algo.eval_envs], elsewhere=True)  # helpers' evaluation steps too
    wall = float(algo.wall_time)
    split = _epoch_split(progress_csv)
    if split is None:
        inside = {key: train[key] + evaluation[key] for key in TIMING_KEYS}
        split = {**inside, "learning_and_overhead_s": max(wall - sum(inside.values()), 0.0)}
    plans = train["high_level_steps"] + work["high_level_steps"]
    return {
        "k": int(train["low_level_steps"] / max(train["high_level_steps"], 1)),
        "train_high_level_steps": int(train["high_level_steps"]),
        "train_low_level_steps": int(train["low_level_steps"]),
        "eval_high_level_steps": int(work["high_level_steps"]),
        "wall_time_s": wall,
        "high_level_steps_per_s": train["high_level_steps"] / max(wall, 1e-9),
        "env_steps_per_s": train["low_level_steps"] / max(wall, 1e-9),
        "time_split_s": split,
        "time_split_fraction": {key: value / max(wall, 1e-9) for key, value in split.items()},
        "plan_ms_mean": 1e3 * (train["plan_s"] + work["plan_s"]) / max(plans, 1),
    }


def plot_curves(progress_csv: Path, out_png: Path, title: str = "") -> Path | None:
    """Training (episode) and evaluation return / cost against environment steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with Path(progress_csv).open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return None

    def column(name: str) -> tuple[list[float], list[float]]:
        xs, ys = [], []
        for row in rows:
            if row.get(name) not in (None, ""):
                xs.append(float(row["env_steps"]))
                ys.append(float(row[name]))
        return xs, ys

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for axis, metric in zip(axes, ("return", "cost"), strict=True):
        for name, style in ((f"ep_{metric}", "-"), (f"eval_{metric}", "o--")):
            xs, ys = column(name)
            if xs:
                axis.plot(xs, ys, style, label=name.replace("_", " "), markersize=3)
        axis.set_xlabel("high-level steps")
        axis.set_ylabel(f"episode {metric}")
        axis.grid(alpha=0.3)
        axis.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return out_png


def record_episode(
    algo: Any, cfg: Any, out_gif: Path, seed: int, frame_every: int = 5, fps: float = 20.0
) -> dict[str, Any]:
    """Run one evaluation episode (mean action, evaluation planner) and save it as a GIF."""
    from hydra.utils import instantiate

    from semdp.envs import make_env
    from sims.rendering import save_gif

    env_cfg = cfg.env
    spec = env_cfg.get("eval_wrapper") or env_cfg.get("wrapper")
    wrapper = functools.partial(instantiate(spec), frame_every=frame_every)
    kwargs = {**dict(env_cfg.get("kwargs") or {}), "render_mode": "rgb_array"}
    env = make_env(env_cfg.id, kwargs, wrapper, bool(env_cfg.get("add_zero_cost", False)))
    semdp = find_semdp(env)
    obs, _ = env.reset(seed=seed)
    ret = cost = 0.0
    steps = 0
    while True:
        action = algo.predict(np.asarray(obs)[None], deterministic=True)[0]
        obs, reward, terminated, truncated, info = env.step(action)
        ret += float(reward)
        cost += float(info["cost"])
        steps += 1
        if terminated or truncated:
            break
    frames = semdp.frames if semdp is not None else []
    if frames:
        save_gif(frames, out_gif, fps=fps)
    env.close()
    return {"path": str(out_gif), "seed": seed, "return": ret, "cost": cost,
            "high_level_steps": steps, "frames": len(frames)}


def after_training(
    algo: Any,
    cfg: Any,
    run_dir: str | Path,
    metrics: dict[str, Any],
    gif: bool = True,
    curves: bool = True,
    frame_every: int = 5,
) -> dict[str, Any]:
    """``post_train`` hook: add the throughput split to ``metrics`` (key ``"semdp"``), write
    ``curves.png`` and ``eval_episode.gif`` into the run directory, and print a summary."""
    run_dir = Path(run_dir)
    stats = throughput(algo, run_dir / "progress.csv")
    metrics = {**metrics, "semdp": stats}
    if curves:
        try:
            plot_curves(run_dir / "progress.csv", run_dir / "curves.png",
                        title=f"{metrics.get('label') or metrics.get('algo')} on {cfg.env.id}")
        except Exception as exc:  # an artefact must not fail a finished run
            logger.warning("could not plot curves: %r", exc)
    if gif:
        try:
            metrics["gif_episode"] = record_episode(
                algo, cfg, run_dir / "eval_episode.gif", seed=int(cfg.seed) + 20_000,
                frame_every=frame_every,
            )
        except Exception as exc:
            logger.warning("could not record the evaluation GIF: %r", exc)
    split = stats["time_split_fraction"]
    ev = metrics.get("eval") or {}
    print(
        f"SEMDP {cfg.env.id}: {stats['high_level_steps_per_s']:.0f} high-level steps/s, "
        f"{stats['env_steps_per_s']:.0f} env steps/s; time split "
        + ", ".join(f"{key.removesuffix('_s')} {100 * value:.0f}%" for key, value in split.items())
        + (f"; eval return {ev.get('return_mean', math.nan):.2f}, cost "
           f"{ev.get('cost_mean', math.nan):.3f} over {ev.get('episodes')} episodes" if ev else "")
    )
    return metrics
