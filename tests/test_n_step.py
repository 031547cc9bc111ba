"""n-step returns for SAC (semdp/algos/sac/n_step.py): hand-computed rows, rows rebuilt from a
one-step run of the same seed and the learner's gamma^m bootstrap (exact resume with windows
pending: tests/test_sac_learner.py)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import torch
from hydra.errors import InstantiationException
from omegaconf import DictConfig

from semdp.algos.sac.learner import LearnerSettings, SACLearner
from semdp.algos.sac.n_step import NStepReturns
from semdp.cli.train import build_algorithm


def _push(acc: NStepReturns, t: int, reward: float, end: str = "") -> tuple[np.ndarray, ...]:
    """One step of a single env whose observation is the time t and action -t."""
    return acc.push(np.array([[t]], np.float32), np.array([[-t]], np.float32),
                    np.array([reward]), np.array([10 * reward]), np.array([[t + 1]], np.float32),
                    np.array([float(end == "terminated")]), np.array([end != ""]))


@pytest.mark.parametrize("end", ["truncated", "terminated"])
def test_rows_are_hand_computed_n_step_returns(end: str) -> None:
    """n = 3, gamma = 1/2, rewards 1..5, the episode ending at the fifth step."""
    acc = NStepReturns(3, 0.5, 1)
    assert _push(acc, 0, 1.0)[0].shape == (0, 1) and _push(acc, 1, 2.0)[2].size == 0
    obs, act, rew, cost, nxt, term, hor = _push(acc, 2, 3.0)
    np.testing.assert_array_equal(obs, [[0]])
    np.testing.assert_array_equal(act, [[0]])
    np.testing.assert_array_equal(rew, [1 + 2 / 2 + 3 / 4])
    np.testing.assert_array_equal(cost, [10 * (1 + 2 / 2 + 3 / 4)])
    np.testing.assert_array_equal(nxt, [[3]])
    np.testing.assert_array_equal(term, [0])
    np.testing.assert_array_equal(hor, [3])
    rew = _push(acc, 3, 4.0)[2]
    np.testing.assert_array_equal(rew, [2 + 3 / 2 + 4 / 4])
    obs, act, rew, cost, nxt, term, hor = _push(acc, 4, 5.0, end)
    np.testing.assert_array_equal(obs, [[2], [3], [4]])
    np.testing.assert_array_equal(act, [[-2], [-3], [-4]])
    np.testing.assert_array_equal(rew, [3 + 4 / 2 + 5 / 4, 4 + 5 / 2, 5])
    np.testing.assert_array_equal(nxt, [[5], [5], [5]])  # the final observation
    np.testing.assert_array_equal(term, [float(end == "terminated")] * 3)
    np.testing.assert_array_equal(hor, [3, 2, 1])
    assert all(not window for window in acc.pending)
    assert _push(acc, 0, 7.0)[2].size == 0  # the next episode starts a new window


def test_one_step_rows_are_the_transitions_themselves() -> None:
    acc = NStepReturns(1, 0.9, 2)
    rng = np.random.default_rng(0)
    obs, act, nxt = rng.normal(size=(2, 4)), rng.normal(size=(2, 2)), rng.normal(size=(2, 4))
    rows = acc.push(obs, act, np.array([1.5, -2.0]), np.array([0.0, 1.0]), nxt,
                    np.array([0.0, 1.0]), np.array([False, True]))
    for got, want in zip(rows, (obs, act, [1.5, -2.0], [0.0, 1.0], nxt, [0.0, 1.0], [1, 1]),
                         strict=True):
        np.testing.assert_array_equal(got, np.asarray(want, np.float32))


def test_rejects_bad_settings_and_a_checkpoint_of_another_n() -> None:
    with pytest.raises(ValueError, match="n must be >= 1"):
        NStepReturns(0, 0.9, 1)
    with pytest.raises(ValueError, match="num_envs must be >= 1"):
        NStepReturns(2, 0.9, 0)
    with pytest.raises(ValueError, match="windows of 2, this run 3"):
        NStepReturns(3, 0.9, 1).load_state_dict(NStepReturns(2, 0.9, 1).state_dict())


def _n_step_oracle(steps: list[dict[str, np.ndarray]], n: int, gamma: float
                   ) -> list[tuple[Any, ...]]:
    """n-step rows from one-step transitions, written independently of the class: for every
    step of every env, sum forward until n steps or the episode's end; the rows in the order a
    collector emits them (by the step completing them, then env, then start)."""
    rows = []
    num_envs = len(steps[0]["rewards"])
    for t in range(len(steps)):
        for i in range(num_envs):
            reward, m = 0.0, 0
            while t + m < len(steps):
                reward += gamma ** m * float(steps[t + m]["rewards"][i])
                m += 1
                if m == n or steps[t + m - 1]["ended"][i]:
                    break
            last = steps[t + m - 1]
            if m == n or last["ended"][i]:  # else still pending when the epoch ends
                terminated = float(last["terminated"][i]) if last["ended"][i] else 0.0
                rows.append(((t + m - 1, i, t), steps[t]["obs"][i], reward, terminated, m,
                             last["next_obs"][i]))
    return sorted(rows, key=lambda row: row[0])


def test_sac_stores_the_n_step_rows_of_its_one_step_transitions(
    tiny_train: Callable[..., DictConfig],
) -> None:
    """Before learning starts the actions are the seed's uniform draws, so a one-step and a
    3-step run see the same transitions: the 3-step buffer must hold, row for row, what the
    oracle sums from the one-step buffer."""
    gamma = 0.5
    overrides = ("algo.learning_starts=10000", "total_steps=400", "budget.steps_per_epoch=400",
                 f"algo.gamma={gamma}")
    one = build_algorithm(tiny_train("sac", *overrides))
    three = build_algorithm(tiny_train("sac", *overrides, "algo.n_step=3"))
    torch.manual_seed(1)
    one.train_epoch()
    torch.manual_seed(1)
    three.train_epoch()
    n_envs, b = one.num_envs, one.buffer.arrays
    steps = []
    for t in range(one.buffer.size // n_envs):
        rows = slice(t * n_envs, (t + 1) * n_envs)
        following = b["obs"][rows.stop:rows.stop + n_envs]  # a reset follows a time-out
        timed_out = (np.any(following != b["next_obs"][rows], axis=1) if len(following)
                     else np.zeros(n_envs, bool))
        steps.append({"obs": b["obs"][rows], "rewards": b["rewards"][rows],
                      "terminated": b["terminated"][rows], "next_obs": b["next_obs"][rows],
                      "ended": (b["terminated"][rows] == 1) | timed_out})
    assert sum(s["ended"].sum() for s in steps) >= 2  # episodes end inside the epoch
    want = _n_step_oracle(steps, 3, gamma)
    c = three.buffer.arrays
    assert three.buffer.size == len(want)
    for k, (_, obs, reward, terminated, m, next_obs) in enumerate(want):
        np.testing.assert_array_equal(c["obs"][k], obs)
        np.testing.assert_array_equal(c["next_obs"][k], next_obs)
        assert (c["terminated"][k], c["horizons"][k]) == (terminated, m)
        assert c["rewards"][k] == pytest.approx(reward, rel=1e-6)
    assert {int(m) for m in c["horizons"][:three.buffer.size]} == {1, 2, 3}


def test_the_learner_bootstraps_gamma_to_the_horizon() -> None:
    """With every row 2 steps long, gamma = 1/2 and n-step rows is gamma = 1/4 and one-step
    rows: the same parameters after the same updates (powers of 2 are exact)."""
    n = 64
    gen = torch.Generator().manual_seed(0)
    storage = {"obs": torch.randn(n, 5, generator=gen),
               "next_obs": torch.randn(n, 5, generator=gen),
               "actions": torch.rand(n, 2, generator=gen) * 2 - 1,
               "rewards": torch.randn(n, generator=gen),
               "terminated": (torch.rand(n, generator=gen) < 0.2).float(),
               "horizons": torch.full((n,), 2.0)}

    def trained(gamma: float, n_step: int) -> list[torch.Tensor]:
        torch.manual_seed(0)
        settings = LearnerSettings(5, 2, (8, 8), 3e-4, 1e-3, gamma, 0.005, 16, 2, 1.0, True,
                                   -2.0, 1e-3, 0, n_step=n_step)
        learner = SACLearner(settings, storage)
        learner.run(6, n)
        return [p.detach().clone() for p in (*learner.critic.parameters(),
                                             *learner.actor.parameters())]

    for a, b in zip(trained(0.5, 3), trained(0.25, 1), strict=True):
        assert torch.equal(a, b)
    assert not all(torch.equal(a, b) for a, b in zip(trained(0.5, 3), trained(0.5, 1),
                                                      strict=True))


def test_sac_rejects_n_step_below_one(tiny_train: Callable[..., DictConfig]) -> None:
    with pytest.raises(InstantiationException, match="n_step must be >= 1"):
        build_algorithm(tiny_train("sac", "algo.n_step=0"))
