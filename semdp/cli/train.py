"""``semdp-train``: the Hydra training app (docs/design.md).

    semdp-train algo=ppo_lag env=point_goal1 seed=0 cost_limit=25
    semdp-train -m algo=ppo_lag,sp_ppo_lag seed=0,1,2      # joblib launcher, 2 jobs
    semdp-train algo=sac env=pendulum budget=ci
    semdp-train resume=outputs/train/<run dir>
    semdp-train -m ... hydra.sweep.dir=<dir> resume=auto   # rerun a sweep: finished jobs are
                                                           # skipped, unfinished ones continue

Writes the run-directory contract: ``config.yaml`` (resolved), ``progress.csv``,
``checkpoints/last.pt`` and ``metrics.json``. A run that raises leaves its partial CSV and a
``metrics.json`` with ``status: failed`` and the error; inside a multirun the error is recorded
and the sweep goes on, in a single run it is re-raised.
"""

from __future__ import annotations

import json
import logging
import traceback
from pathlib import Path
from typing import Any

import hydra
import torch
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf, open_dict

from semdp.algos.base import CHECKPOINT_NAME, Algorithm
from semdp.build import ConfigError, build_algorithm, validate_config
from semdp.cli.one_line import discard_set_up, one_line, run_app, traceback_wanted
from semdp.cli.override_types import wrong_types
from semdp.cli.run_logging import progress_logging
from semdp.common.checkpoint_files import CheckpointError, check_checkpoint_file
from semdp.common.logger import write_metrics
from semdp.paths import CONF_DIR
from semdp.run_config import load_run_config
from solvers.workers import HelperError

logger = logging.getLogger(__name__)


def _choices(cfg: DictConfig) -> tuple[str, str]:
    try:
        choices = HydraConfig.get().runtime.choices
        return str(choices["algo"]), str(choices["env"])
    except (ValueError, KeyError):  # composed outside a Hydra app (tests)
        return str(cfg.algo._target_).rsplit(".", 1)[-1], str(cfg.env.id)


def _names(cfg: DictConfig) -> tuple[str, str]:
    """(algorithm, env) names for metrics.json: the config's own, else Hydra's choices."""
    if cfg.get("algo_name"):
        env = cfg.get("env_name")
        return str(cfg.algo_name), str(env) if env else _choices(cfg)[1]
    return _choices(cfg)


def _flat(node: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(node, dict):
        out: dict[str, Any] = {}
        for key, value in node.items():
            out.update(_flat(value, f"{prefix}{key}."))
        return out
    return {prefix[:-1]: node}


#: Top-level keys that no run reads: ``resume``, and the tables whose values reach the run only
#: through interpolations into the keys compared (``budget``: into ``total_steps``,
#: ``algo.steps_per_epoch``, ...; ``robot``: into ``env``; ``preset``: the per-preset budget
#: tables of configs saved before conf/budget/ held them).
_NOT_RUN = ("resume", "budget", "robot", "preset")
#: Keys that choose how a run of an algorithm (``algo._target_``) computes, not what: kernels
#: that give the same floats (their tests compare them bit for bit), so a run saved with the
#: other choice continues unchanged.
_SAME_NUMBERS: dict[str, tuple[str, ...]] = {"semdp.algos.SAC": ("algo.gradients",)}


def _config_differences(saved: DictConfig, wanted: DictConfig) -> list[str]:
    """Dotted keys whose resolved values differ between two run configs (:data:`_NOT_RUN` and
    :data:`_SAME_NUMBERS` aside)."""
    a = _flat(OmegaConf.to_container(saved, resolve=True))
    b = _flat(OmegaConf.to_container(wanted, resolve=True))
    neutral = _SAME_NUMBERS.get(a.get("algo._target_"), ()) if (
        a.get("algo._target_") == b.get("algo._target_")) else ()
    return sorted(k for k in a.keys() | b.keys()
                  if k.split(".", 1)[0] not in _NOT_RUN and k not in neutral
                  and a.get(k) != b.get(k))


def _auto_resume(cfg: DictConfig, run_dir: Path) -> str | dict[str, Any] | None:
    """``resume=auto``: what to do with ``run_dir`` (a sweep job's directory, rerun).

    Returns the finished run's metrics (nothing to do), the directory to resume (a checkpoint of
    the same configuration), or None (nothing there yet: start afresh). A checkpoint of another
    configuration is an error: the rerun would silently mix two experiments.
    """
    if not (run_dir / "config.yaml").is_file():
        return None
    try:
        saved = load_run_config(run_dir)
    except ValueError as exc:
        raise ConfigError(f"resume=auto: {exc}") from None
    wanted = cfg.copy()
    with open_dict(wanted):
        wanted.algo_name, wanted.env_name = _names(cfg)
    differences = _config_differences(saved, wanted)
    if differences:
        shown = ", ".join(f"{k} ({OmegaConf.select(saved, k)!r} there, "
                          f"{OmegaConf.select(wanted, k)!r} now)" for k in differences[:3])
        raise ConfigError(f"resume=auto: {run_dir} holds a run of another configuration: {shown}"
                          f"{' ...' if len(differences) > 3 else ''}; pick another output "
                          f"directory, or resume={run_dir} to continue it as it was saved")
    metrics_path = run_dir / "metrics.json"
    if metrics_path.is_file():
        metrics = json.loads(metrics_path.read_text())
        if metrics.get("status") == "completed":
            return dict(metrics)
    if not (run_dir / "checkpoints" / CHECKPOINT_NAME).is_file():
        return None
    return str(run_dir)


def run(cfg: DictConfig, run_dir: str | Path) -> dict[str, Any]:
    """Train (or resume) one run into ``run_dir``; return the final ``metrics.json`` content.

    ``resume``: null (a new run), a run directory (continue it with its saved config), or
    ``auto`` (``run_dir`` itself: return its metrics if it finished, continue it if it has a
    checkpoint of the same configuration, else start it).
    """
    run_dir = Path(run_dir)
    resume = cfg.get("resume")
    threads = int(cfg.get("torch_threads", 1))
    if resume == "auto":
        found = _auto_resume(cfg, run_dir)
        if isinstance(found, dict):
            logger.info("resume=auto: %s already completed; nothing to do", run_dir)
            return found
        resume = found
        if resume is None:
            with open_dict(cfg):
                cfg.resume = None
    if resume:
        run_dir = Path(resume)
        ckpt = run_dir / "checkpoints" / CHECKPOINT_NAME
        if not ckpt.is_file() or not (run_dir / "config.yaml").is_file():
            raise ConfigError(f"resume={resume}: no config.yaml and checkpoints/{CHECKPOINT_NAME}")
        try:
            check_checkpoint_file(ckpt)
        except CheckpointError as exc:
            raise ConfigError(f"resume={resume}: {exc}") from None
        try:
            cfg = load_run_config(run_dir)
        except ValueError as exc:
            raise ConfigError(f"resume={resume}: {exc}") from None
        with open_dict(cfg):
            cfg.resume = str(resume)
    validate_config(cfg)
    torch.set_num_threads(threads)
    run_dir.mkdir(parents=True, exist_ok=True)
    algo_name, env_name = _names(cfg)
    meta = {"algo": algo_name, "env": env_name, "seed": int(cfg.seed)}
    if cfg.get("label"):  # method label for semdp-report (e.g. "Ours w/ gt")
        meta["label"] = str(cfg.label)
    if not resume:
        with open_dict(cfg):
            cfg.algo_name, cfg.env_name = algo_name, env_name
        OmegaConf.save(cfg, run_dir / "config.yaml", resolve=True)
    algo: Algorithm | None = None
    try:
        algo = build_algorithm(cfg)
        if resume:
            algo.load_checkpoint(run_dir / "checkpoints" / CHECKPOINT_NAME)
            logger.info("resuming %s at epoch %d (%d env steps)", run_dir, algo.epoch,
                        algo.env_steps)
        with progress_logging(cfg, algo):  # SEMDP time split, TensorBoard mirror
            metrics = algo.learn(
                total_steps=int(cfg.total_steps), run_dir=run_dir,
                eval_every=int(cfg.eval_every), eval_episodes=int(cfg.eval_episodes),
                final_eval_episodes=int(cfg.final_eval_episodes),
                checkpoint_every=int(cfg.checkpoint_every), resume=bool(resume), metadata=meta,
                eval_workers=int(cfg.get("eval_workers", 1)),
            )
        # Optional post-training hook (e.g. the SEMDP timing split, curves and evaluation GIF):
        # `post_train` (top level or in the env config), a `_partial_` callable
        # hook(algo=, cfg=, run_dir=, metrics=) -> metrics.
        hook_cfg = cfg.get("post_train") or cfg.env.get("post_train")
        if hook_cfg:
            metrics = instantiate(hook_cfg)(algo=algo, cfg=cfg, run_dir=run_dir, metrics=metrics)
            write_metrics(run_dir / "metrics.json", metrics)
        return metrics
    except (Exception, KeyboardInterrupt) as exc:  # record, then let the caller decide
        metrics = {
            "status": "failed", "error": f"{type(exc).__name__}: {exc}", **meta,
            "env_steps": algo.env_steps if algo else 0,
            "wall_time_s": algo.wall_time if algo else 0.0, "eval": None,
        }
        write_metrics(run_dir / "metrics.json", metrics)
        (run_dir / "error.txt").write_text(traceback.format_exc())
        raise


@hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="train")
def app(cfg: DictConfig) -> float | None:
    """The Hydra app; returns the final evaluation return (for sweepers).

    In a single run, bad input (a bad value, or anything raised before the first epoch) ends it
    with one line and removes the run directory it had set up; a run that fails while training
    keeps its directory (``metrics.json``, ``error.txt`` with the traceback, the checkpoint)
    and names it. In a multirun the error is recorded and the sweep goes on.
    """
    hydra_cfg = HydraConfig.get()
    multirun = hydra_cfg.mode == RunMode.MULTIRUN
    output_dir = Path(hydra_cfg.runtime.output_dir)
    try:
        reason = wrong_types(cfg, "train", hydra_cfg.overrides.task)
        if reason is not None:
            raise ConfigError(reason)
        metrics = run(cfg, output_dir)
    except ConfigError as exc:
        if not multirun:  # one line naming the key, no traceback
            discard_set_up(output_dir, f"{hydra_cfg.job.name}.log")
            raise SystemExit(f"semdp-train: {exc}") from None
        logger.error("bad config (the sweep continues): %s", exc)
        return None
    except HelperError as exc:  # one line naming the helper; the traceback is in error.txt
        resume = cfg.get("resume")
        run_dir = resume if resume and resume != "auto" else output_dir
        line = (f"{str(exc).splitlines()[0]}; the last checkpoint is kept, continue with: "
                f"semdp-train resume={run_dir}")
        if not multirun:
            raise SystemExit(f"semdp-train: {line}") from None
        logger.error("run failed (the sweep continues): %s", line)
        return None
    except Exception as exc:
        if multirun:
            logger.error("run failed (recorded in metrics.json; the sweep continues): %s", exc)
            return None
        if traceback_wanted():
            raise
        resume = cfg.get("resume")
        run_dir = Path(resume) if resume and resume != "auto" else output_dir
        if not (run_dir / "progress.csv").is_file():  # nothing trained: bad input
            discard_set_up(output_dir, f"{hydra_cfg.job.name}.log")
            raise SystemExit(f"semdp-train: {type(exc).__name__}: {one_line(exc)}") from None
        raise SystemExit(f"semdp-train: {type(exc).__name__}: {one_line(exc)} (traceback in "
                         f"{run_dir / 'error.txt'})") from None
    ev = metrics.get("eval")
    return None if not ev else float(ev["return_mean"])


def main() -> None:
    """Console entry point (``semdp-train``): the Hydra app, every error in one line."""
    run_app(app, "semdp-train")


if __name__ == "__main__":
    main()
