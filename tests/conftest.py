"""Shared fixtures: compose the training config from ``conf/`` with Hydra's compose API."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

# isort: off
import semdp  # noqa: F401  (before torch: pins the CPU kernels, semdp.numerics)
import torch

# isort: on

# Checkpoints written by the tests are signed with a key of their own, not the user's
# (semdp/common/checkpoint_files.py); subprocesses inherit it.
os.environ["SEMDP_CHECKPOINT_KEY"] = str(Path(tempfile.mkdtemp(prefix="semdp-test-key-"))
                                         / "checkpoint.key")
os.environ.pop("SEMDP_TRUST_CHECKPOINTS", None)
from omegaconf import DictConfig, open_dict

from semdp.common.seeding import seed_everything
from semdp.configs import compose_config

#: Overrides that shrink any algorithm to a seconds-long run on the test CMDP.
TINY = [
    "env=speed_limit", "budget=ci", "env.num_envs=2", "total_steps=800",
    "budget.steps_per_epoch=200", "eval_every=2", "eval_episodes=2", "final_eval_episodes=3",
]
TINY_ALGO = {
    "ppo": ["algo.update_iters=2", "algo.num_minibatches=4", "algo.hidden_sizes=[16,16]"],
    "ppo_lag": ["algo.update_iters=2", "algo.num_minibatches=4", "algo.hidden_sizes=[16,16]"],
    "sp_ppo_lag": ["algo.update_iters=2", "algo.num_minibatches=4", "algo.hidden_sizes=[16,16]"],
    "trpo": ["algo.critic_iters=2", "algo.hidden_sizes=[16,16]"],
    "trpo_lag": ["algo.critic_iters=2", "algo.hidden_sizes=[16,16]"],
    "cpo": ["algo.critic_iters=2", "algo.hidden_sizes=[16,16]"],
    "sac": ["algo.learning_starts=100", "algo.batch_size=32", "algo.hidden_sizes=[16,16]",
            "algo.buffer_size=5000", "algo.updates_per_step=0.25"],
}


@pytest.fixture(autouse=True)
def _one_torch_thread() -> Iterator[None]:
    """Every test runs torch on one thread, as the training app does (``torch_threads``), so no
    number depends on the machine's cores or ``OMP_NUM_THREADS``."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(autouse=True)
def _seeded_global_generators() -> None:
    """Every test starts from the global generators seeded with 0, as the training app seeds
    them (``seed_everything``), so a test that builds networks itself draws the same weights
    whatever ran before it in the process."""
    seed_everything(0)


def pin_helpers(cfg: DictConfig) -> DictConfig:
    """Replace the on-policy helpers' ``auto`` by the single-process path (``auto`` decides by
    the machine's load; tests choose a path: ``loop=helpers`` or explicit keys for the other)."""
    with open_dict(cfg):
        if cfg.algo.get("vectorization") == "auto":
            cfg.algo.vectorization = "sync"
        if cfg.algo.get("parallel_critics") == "auto":
            cfg.algo.parallel_critics = False
    return cfg


@pytest.fixture
def compose_train() -> Callable[..., DictConfig]:
    """``compose_train(*overrides)`` -> the composed ``train`` config (no Hydra app running),
    helper paths pinned (:func:`pin_helpers`) unless the overrides choose them."""

    def _compose(*overrides: str) -> DictConfig:
        cfg = compose_config("train", overrides)
        chosen = {o.lstrip("+~").split("=", 1)[0] for o in overrides} & {
            "algo.vectorization", "algo.parallel_critics", "loop"}
        return cfg if chosen else pin_helpers(cfg)

    return _compose


@pytest.fixture
def tiny_train(compose_train: Callable[..., DictConfig]) -> Callable[..., DictConfig]:
    """``tiny_train(algo, *extra)`` -> a seconds-long config of ``algo`` on the test CMDP."""

    def _tiny(algo: str, *extra: str) -> DictConfig:
        return compose_train(f"algo={algo}", *TINY, *TINY_ALGO[algo], *extra)

    return _tiny


@pytest.fixture
def crash_in_epoch_3(monkeypatch: pytest.MonkeyPatch) -> Callable[[type], Callable[..., Any]]:
    """``crash_in_epoch_3(cls)`` makes ``cls.train_epoch`` raise in the third epoch (index 2)
    and returns the real method, for the test to restore before resuming."""

    def _patch(cls: type) -> Callable[..., Any]:
        original = cls.train_epoch  # type: ignore[attr-defined]

        def crashing(self: Any) -> dict[str, float]:
            if self.epoch == 2:
                raise RuntimeError("simulated crash")
            return original(self)

        monkeypatch.setattr(cls, "train_epoch", crashing)
        return original

    return _patch
