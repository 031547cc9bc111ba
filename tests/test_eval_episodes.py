"""Evaluation episodes shared between processes (semdp/common/vector_episodes.py): the quota and
the groups by hand, the same episodes for any split with a row-wise policy, and the SEMDP
counters of a helper's sub-envs added back."""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest
from omegaconf import DictConfig, open_dict

from semdp.common.vector_episodes import (
    episode_quota,
    evaluate_episodes,
    summarize,
    worker_groups,
)
from semdp.embedded.timing import timing_summary
from semdp.envs import make_vec_env
from solvers.workers import HelperError, fork_available

needs_fork = pytest.mark.skipif(not fork_available(), reason="needs the fork start method")


def test_quota_and_groups_by_hand() -> None:
    assert episode_quota(50, 4) == [13, 13, 12, 12]
    assert episode_quota(3, 4) == [1, 1, 1, 0]
    assert worker_groups([13, 13, 12, 12], 2) == [[0, 1], [2, 3]]
    assert worker_groups([1, 1, 1, 0], 2) == [[0, 1], [2]]
    assert worker_groups([1, 0, 0, 0], 2) == [[0]]  # one sub-env with work: nothing to share
    assert worker_groups([2, 2, 2], 1) == [[0, 1, 2]]
    assert worker_groups([2, 2, 2], 3) == [[0], [1], [2]]


def _pendulums(n: int) -> gym.vector.SyncVectorEnv:
    return gym.vector.SyncVectorEnv(
        [lambda: gym.make("Pendulum-v1", max_episode_steps=30) for _ in range(n)],
        autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)


def _rowwise(obs: np.ndarray) -> np.ndarray:
    """A deterministic policy computed row by row (no batch effects)."""
    return np.clip(-2.0 * obs[:, 2:3] - obs[:, 1:2], -2.0, 2.0).astype(np.float32)


@needs_fork
def test_a_split_evaluation_runs_the_same_episodes_as_one_process() -> None:
    one = evaluate_episodes(_pendulums(4), _rowwise, 10, seed=5, workers=1)
    two = evaluate_episodes(_pendulums(4), _rowwise, 10, seed=5, workers=2)
    assert [r[:2] for r in one] == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2),
                                    (2, 0), (2, 1), (3, 0), (3, 1)]
    assert one == two
    assert len({r[2] for r in one}) == 10  # distinct episodes (a seed mix-up would repeat)
    other_seed = evaluate_episodes(_pendulums(4), _rowwise, 10, seed=6, workers=2)
    assert [r[2] for r in other_seed] != [r[2] for r in one]
    s = summarize(two)
    assert s["episodes"] == 10 and s["return_mean"] == pytest.approx(np.mean([r[2] for r in one]))


def test_a_helper_failure_is_reported_with_its_traceback() -> None:
    if not fork_available():
        pytest.skip("needs the fork start method")
    calls = {"n": 0}  # counted in this process only

    def fails_in_helper(obs: np.ndarray) -> np.ndarray:
        calls["n"] += 1
        if obs.shape[0] == 1:  # the helper's half (sub-env 2 alone) fails
            raise ValueError("planted failure")
        return _rowwise(obs)

    envs = gym.vector.SyncVectorEnv(
        [lambda: gym.make("Pendulum-v1", max_episode_steps=5) for _ in range(3)],
        autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    with pytest.raises(HelperError, match=r"semdp-eval \(pid \d+\) failed:(.|\n)*planted failure"):
        evaluate_episodes(envs, fails_in_helper, 3, seed=0, workers=2)
    assert calls["n"] == 5  # this process ran its two sub-envs' episodes to the end


@needs_fork
def test_semdp_counters_of_the_helper_are_added_back(
    compose_train: Callable[..., DictConfig],
) -> None:
    cfg = compose_train("experiment=semdp", "env.num_envs=2", "++env.kwargs.max_episode_steps=40")
    with open_dict(cfg):
        cfg.env.vector = "semdp.embedded.vector.LockstepVectorEnv"
    envs = make_vec_env(cfg.env, seed=0)
    zeros = lambda obs: np.zeros((obs.shape[0], 2), dtype=np.float32)
    results = evaluate_episodes(envs, zeros, 4, seed=3, workers=2)
    assert len(results) == 4
    # 40 env steps per episode, k = 10: 4 high-level steps per episode; sub-env 1's two
    # episodes ran in the helper: counted as work done, not in this process's wall time
    here, work = timing_summary([envs]), timing_summary([envs], elsewhere=True)
    assert (here["high_level_steps"], work["high_level_steps"]) == (8, 16)
    assert (here["low_level_steps"], work["low_level_steps"]) == (80, 160)
    assert work["plan_s"] > here["plan_s"] > 0
