"""Shared fixtures: compose the training config from ``conf/`` with Hydra's compose API."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from omegaconf import DictConfig

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


@pytest.fixture
def compose_train() -> Callable[..., DictConfig]:
    """``compose_train(*overrides)`` -> the composed ``train`` config (no Hydra app running)."""

    def _compose(*overrides: str) -> DictConfig:
        return compose_config("train", overrides)

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
