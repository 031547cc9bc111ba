"""Rebuild a trained run from its directory: ``config.yaml`` with ``checkpoints/last.pt``, or
``policy.pt`` alone (docs/design.md, "The run directory").
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf

from semdp.algos.base import CHECKPOINT_NAME, POLICY_NAME, Algorithm
from semdp.build import build_algorithm
from semdp.common.checkpoint_files import load_checkpoint_file
from semdp.common.policy_files import PolicyFileError, load_data
from semdp.run_config import load_run_config


def load_trained(
    run_dir: str | Path, cfg: DictConfig | None = None
) -> tuple[Algorithm, DictConfig]:
    """Rebuild the algorithm of a finished run from ``config.yaml`` and ``checkpoints/last.pt``,
    or from its trained policy alone (``policy.pt``, what reference folders keep).

    Sets torch's thread count to the run's ``torch_threads`` (1 by default), as training did:
    float reductions depend on it, so an evaluation is reproducible on any machine.

    Args:
        run_dir: the run directory.
        cfg: the config to build from (e.g. the saved one with evaluation-time changes);
            ``None`` = the run's ``config.yaml``.

    The checkpoint, when present, is unpickled whole (it holds the environments): trust it as
    your own run's only. ``policy.pt`` is read as data (:mod:`semdp.common.policy_files`).

    Raises:
        ValueError: ``run_dir`` lacks ``config.yaml`` or both the checkpoint and the policy, or
            they were written by another algorithm than the config's.
        PolicyFileError: a ``policy.pt`` that is not plain data, or is empty or truncated.
    """
    run_dir = Path(run_dir)
    ckpt = run_dir / "checkpoints" / CHECKPOINT_NAME
    policy = run_dir / POLICY_NAME
    if not (run_dir / "config.yaml").is_file() or not (ckpt.is_file() or policy.is_file()):
        raise ValueError(f"{run_dir} is not a finished run dir (needs config.yaml and "
                         f"checkpoints/{ckpt.name} or {POLICY_NAME})")
    if cfg is None:
        cfg = load_run_config(run_dir)
    torch.set_num_threads(int(cfg.get("torch_threads", 1) or 1))
    algo = build_algorithm(cfg)
    if not policy.is_file():  # a run stopped before the end: its own (signed) checkpoint
        state = load_checkpoint_file(ckpt)["algo"]
        check_checkpoint_fits(algo, state, cfg)
        algo.load_state_dict(state)
        return algo, cfg
    saved = load_data(policy, "policy")
    if saved.get("algorithm") != type(algo).__name__:
        raise ValueError(f"{POLICY_NAME} was written by {saved['algorithm']}, config.yaml "
                         f"builds {type(algo).__name__}")
    try:
        algo.load_policy_state(saved["policy"])
    except (KeyError, RuntimeError) as exc:
        text = " ".join(str(exc).split())[:300]
        raise PolicyFileError(f"{policy}: does not fit the network config.yaml builds "
                              f"({text})") from None
    algo.epoch, algo.env_steps = int(saved["epoch"]), int(saved["env_steps"])
    return algo, cfg


def check_checkpoint_fits(algo: Algorithm, state: Mapping[str, Any], cfg: DictConfig) -> None:
    """Raise ``ValueError`` unless ``state`` has the keys of ``algo``'s own checkpoints."""
    expected, found = set(algo.state_dict()), set(state)
    if expected != found:
        name = cfg.get("algo_name") or str(cfg.algo.get("_target_", "?"))
        raise ValueError(
            f"checkpoints/{CHECKPOINT_NAME} was not written by {name} "
            f"({type(algo).__name__}, the algorithm of config.yaml): missing "
            f"{sorted(expected - found)}, unexpected {sorted(found - expected)}"
        )


def env_config(cfg: DictConfig) -> dict[str, Any]:
    """The run's env node as a plain dict (interpolations resolved, wrappers left as nodes)."""
    node = OmegaConf.to_container(cfg.env, resolve=True)
    if not isinstance(node, dict):
        raise ValueError(f"cfg.env must be a mapping, got {type(node).__name__}")
    node.pop("post_train", None)
    return node
