"""Evaluate a finished run and write ``<run dir>/eval_<time>/`` (docs/evaluation.md).

The directory holds ``metrics.json`` (per-episode results, their means in ``eval``, the
arguments, the evaluated settings), ``config.yaml`` (the config that was evaluated), a copy of
the run's ``progress.csv`` and, with ``video=true``, the first episode as MP4 or GIF. Its
``metrics.json`` has the fields ``semdp-report`` reads (``status``, ``label``, ``env``, ``seed``,
``eval``), so an evaluation variant shows up as a method of its own beside the trained runs; its
label is ``label=`` when given, else the run's label with ``[eval ...]`` and the changes.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydra.errors import InstantiationException
from omegaconf import DictConfig, OmegaConf

from semdp.algos.base import CHECKPOINT_NAME, EVAL_SEED_OFFSET, POLICY_NAME, Algorithm
from semdp.common.checkpoint_files import CheckpointError
from semdp.common.logger import write_metrics
from semdp.common.policy_files import PolicyFileError
from semdp.evaluation.config_edits import edited_config
from semdp.evaluation.environment import build_evaluation_env
from semdp.evaluation.episodes import play_episode, summarise
from semdp.evaluation.errors import EvalError
from semdp.evaluation.loading import load_trained
from semdp.evaluation.options import EvalOptions, parse_arguments
from semdp.evaluation.transfer_variant import LAYOUT_SEED
from semdp.evaluation.zoo import resolve
from semdp.rendering.video import write_video
from semdp.run_config import load_run_config

DEFAULT_EPISODES = 50
#: variant=transfer: the stand-in's 10 fixed layouts (semdp/evaluation/transfer_variant.py).
TRANSFER_LAYOUTS = 10


def check_run_dir(run_dir: Path) -> None:
    """Raise :class:`EvalError` unless ``run_dir`` holds ``config.yaml`` and the checkpoint or
    the trained policy."""
    if not run_dir.is_dir():
        raise EvalError(f"{run_dir}: no such run directory")
    missing = [name for name in ("config.yaml",) if not (run_dir / name).is_file()]
    if not ((run_dir / "checkpoints" / CHECKPOINT_NAME).is_file()
            or (run_dir / POLICY_NAME).is_file()):
        missing.append(f"checkpoints/{CHECKPOINT_NAME} or {POLICY_NAME}")
    if missing:
        raise EvalError(f"{run_dir} is not a finished run: no {' and no '.join(missing)}")


def episode_seeds(options: EvalOptions, cfg: DictConfig) -> list[int]:
    """``seeds=``, else ``episodes`` consecutive seeds from ``seed=`` (default: the run's seed +
    the evaluation offset of training, or the transfer layouts' first seed)."""
    if options.seeds is not None:
        return list(options.seeds)
    transfer = options.variant == "transfer"
    episodes = options.episodes or (TRANSFER_LAYOUTS if transfer else DEFAULT_EPISODES)
    first = options.seed
    if first is None:
        first = LAYOUT_SEED if transfer else int(cfg.get("seed", 0)) + EVAL_SEED_OFFSET
    return [first + i for i in range(episodes)]


def _load(run_dir: Path, cfg: DictConfig) -> Algorithm:
    try:
        algo, _ = load_trained(run_dir, cfg)
    except (PolicyFileError, CheckpointError) as exc:
        raise EvalError(str(exc)) from None
    except (ValueError, TypeError, KeyError, InstantiationException) as exc:
        text = " ".join(str(exc).split())
        raise EvalError(text if "checkpoints/" in text else
                        f"cannot build the run with these overrides: {text}"[:400]) from None
    return algo


def _out_dir(root: Path) -> Path:
    stamp = dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    out, n = root / f"eval_{stamp}", 1
    while out.exists():
        out, n = root / f"eval_{stamp}_{n}", n + 1
    return out


def _label(source: dict[str, Any], cfg: DictConfig, options: EvalOptions) -> str:
    if any(o.key == "label" for o in options.overrides) and cfg.get("label"):
        return str(cfg.label)
    base = source.get("label") or cfg.get("label") or source.get("algo") or cfg.get("algo_name")
    changes = options.changes
    return f"{base} [eval{' ' + ' '.join(changes) if changes else ''}]"


@dataclass
class Played:
    """The episodes of one evaluation, before anything is written (:func:`play_run`)."""

    run_dir: Path
    out_root: Path | None
    options: EvalOptions
    cfg: DictConfig
    seeds: list[int]
    episodes: list[dict[str, Any]]
    frames: list[Any]
    settings: dict[str, Any]
    fps: float
    wall_time_s: float


def play_run(run_dir: str | Path, arguments: list[str] | tuple[str, ...]) -> Played:
    """Play the evaluation episodes of ``run_dir`` (or ``zoo:<name>``) under ``arguments``;
    write nothing.

    Raises:
        EvalError: a bad run directory, zoo name or argument, an unknown key, or a checkpoint
            of another algorithm.
    """
    run_dir, out_root = resolve(str(run_dir))
    check_run_dir(run_dir)
    options = parse_arguments(list(arguments))
    try:
        saved = load_run_config(run_dir)
    except ValueError as exc:
        raise EvalError(str(exc)) from None
    cfg = edited_config(saved, options)
    seeds = episode_seeds(options, cfg)
    start = time.perf_counter()
    algo = _load(run_dir, cfg)
    ev = build_evaluation_env(cfg, options.variant, options.video_size if options.video else None,
                              options.video_every)
    episodes, frames = [], []
    for i, seed in enumerate(seeds):
        episodes.append(play_episode(algo, ev, seed, record=options.video and i == 0,
                                     sampled=options.actions == "sampled"))
        if i == 0 and ev.recorder is not None:
            frames = ev.recorder.frames
    ev.env.close()
    fps = float(ev.env.metadata.get("render_fps", 50)) / options.video_every
    return Played(run_dir, out_root, options, cfg, seeds, episodes, frames, ev.settings, fps,
                  time.perf_counter() - start)


def evaluate_run(run_dir: str | Path, arguments: list[str]) -> tuple[Path, dict[str, Any]]:
    """Evaluate ``run_dir`` (or a zoo entry ``zoo:<name>``, :mod:`semdp.evaluation.zoo`) under
    ``arguments``; return the new directory and its metrics.

    Raises:
        EvalError: a bad run directory, zoo name or argument, an unknown key, or a checkpoint
            of another algorithm (nothing is written then).
    """
    played = play_run(run_dir, arguments)
    run_dir, options, cfg, seeds, frames = (played.run_dir, played.options, played.cfg,
                                            played.seeds, played.frames)
    source_file = run_dir / "metrics.json"
    source = json.loads(source_file.read_text()) if source_file.is_file() else {}
    out_dir = _out_dir(played.out_root or run_dir)
    out_dir.mkdir(parents=True)
    video = None
    if options.video:
        fps = played.fps
        try:
            path = write_video(frames, out_dir / f"episode_{seeds[0]}", fps=fps)
        except Exception:
            shutil.rmtree(out_dir, ignore_errors=True)
            raise
        video = {"path": str(path), "format": path.suffix[1:], "seed": seeds[0],
                 "frames": len(frames), "every": options.video_every, "fps": fps,
                 "size": int(frames[0].shape[1])}
    OmegaConf.save(cfg, out_dir / "config.yaml")
    if (run_dir / "progress.csv").is_file():
        shutil.copy(run_dir / "progress.csv", out_dir / "progress.csv")
    wrapper = cfg.env.get("eval_wrapper") or cfg.env.get("wrapper")
    planner = wrapper.get("planner") if OmegaConf.is_dict(wrapper) else None
    metrics = {
        "status": "completed", "error": None,
        "label": _label(source, cfg, options),
        "algo": source.get("algo") or cfg.get("algo_name"),
        "env": source.get("env") or cfg.get("env_name"),
        "seed": source.get("seed", cfg.get("seed")),
        "env_steps": source.get("env_steps"),
        "evaluation_of": str(run_dir),
        "arguments": list(arguments),
        "settings": {
            **played.settings, "seeds": seeds, "actions": options.actions,
            "planner": OmegaConf.to_container(planner) if OmegaConf.is_config(planner) else None,
            "perception": wrapper.get("perception") if OmegaConf.is_dict(wrapper) else None,
        },
        "wall_time_s": played.wall_time_s,
        "eval": summarise(played.episodes),
        "episodes": played.episodes,
        "video": video,
    }
    write_metrics(out_dir / "metrics.json", metrics)
    return out_dir, metrics
