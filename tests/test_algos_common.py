"""Oracles for the shared RL pieces: GAE, Lagrange (Adam/SGD/PID), self-paced thresholds,
combined advantage, observation normaliser, vector-env info handling and the test CMDP."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from semdp.algos.gae import gae
from semdp.algos.lagrangian import Lagrange, combined_advantage
from semdp.algos.pid_lagrange import PIDLagrange
from semdp.algos.sp_ppo_lag import SelfPacedThresholds
from semdp.common.normalization import RunningNormalizer
from semdp.common.vector_stepping import merged_step_result
from semdp.envs import make_vec_env


def test_gae_matches_hand_computed_case_with_termination_and_timeout() -> None:
    # One env, 4 steps: step 1 terminates, step 3 is a time-out (bootstrapped with V(s_final)=5).
    gamma, lam = 0.9, 0.5
    rewards = np.array([1.0, 2.0, 0.0, 1.0])
    costs = np.array([0.0, 1.0, 1.0, 0.0])
    values = np.array([0.5, 1.0, 2.0, 3.0])
    next_values = np.array([1.0, 99.0, 3.0, 5.0])  # 99 must be ignored (termination)
    terminated = np.array([0, 1, 0, 0])
    ended = np.array([0, 1, 0, 1])
    adv, ret = gae(rewards, values, next_values, terminated, ended, gamma, lam)
    d3 = 1.0 + 0.9 * 5.0 - 3.0  # 2.5, bootstrapped time-out
    d2 = 0.0 + 0.9 * 3.0 - 2.0  # 0.7
    d1 = 2.0 - 1.0  # 1.0, no bootstrap
    d0 = 1.0 + 0.9 * 1.0 - 0.5  # 1.4
    expected = np.array([d0 + 0.45 * d1, d1, d2 + 0.45 * d3, d3])
    np.testing.assert_allclose(adv, expected)
    np.testing.assert_allclose(ret, expected + values)
    cost_values = np.array([0.2, 0.4, 0.1, 0.3])
    cost_next = np.array([0.4, 7.0, 0.3, 0.6])
    adv_c, _ = gae(costs, cost_values, cost_next, terminated, ended, 1.0, 1.0)
    c3 = 0.0 + 0.6 - 0.3
    c2 = 1.0 + 0.3 - 0.1
    c1 = 1.0 - 0.4
    c0 = 0.0 + 0.4 - 0.2
    np.testing.assert_allclose(adv_c, [c0 + c1, c1, c2 + c3, c3])


def test_gae_vectorised_columns_are_independent() -> None:
    rng = np.random.default_rng(0)
    shape = (6, 3)
    args = [rng.normal(size=shape) for _ in range(3)]
    term = rng.integers(0, 2, size=shape)
    end = np.maximum(term, rng.integers(0, 2, size=shape))
    adv, _ = gae(*args, term, end, 0.99, 0.95)
    for j in range(3):
        col, _ = gae(*(a[:, j] for a in args), term[:, j], end[:, j], 0.99, 0.95)
        np.testing.assert_allclose(adv[:, j], col)


def test_gae_rejects_bad_gamma_and_shapes() -> None:
    z = np.zeros(3)
    with pytest.raises(ValueError, match="gamma"):
        gae(z, z, z, z, z, 1.5, 0.9)
    with pytest.raises(ValueError, match="shapes"):
        gae(z, np.zeros(2), z, z, z, 0.9, 0.9)


def test_lagrange_sgd_step_is_eq_2_10_and_projects_to_zero() -> None:
    lag = Lagrange(cost_limit=10.0, multiplier_init=0.5, lr=0.1, optimizer="sgd")
    assert lag.update(12.0) == pytest.approx(0.7)  # violated: lambda + lr (J_c - d)
    assert lag.update(0.0) == 0.0  # 0.7 - 1.0 < 0 -> projected onto lambda >= 0
    assert lag.update(5.0) == 0.0  # stays at the bound while satisfied


def test_lagrange_adam_moves_by_lr_in_the_direction_of_the_violation() -> None:
    up = Lagrange(cost_limit=25.0, multiplier_init=1.0, lr=0.035)
    assert up.update(40.0) == pytest.approx(1.035, abs=1e-6)  # Adam's first step = lr * sign
    down = Lagrange(cost_limit=25.0, multiplier_init=1.0, lr=0.035)
    assert down.update(10.0) == pytest.approx(0.965, abs=1e-6)
    capped = Lagrange(cost_limit=0.0, multiplier_init=1.0, lr=5.0, upper_bound=2.0)
    assert capped.update(100.0) == 2.0


def test_lagrange_state_dict_round_trip_continues_identically() -> None:
    a = Lagrange(cost_limit=5.0)
    for cost in (9.0, 7.0):
        a.update(cost)
    b = Lagrange(cost_limit=1.0)
    b.load_state_dict(a.state_dict())
    assert [a.update(c) for c in (3.0, 8.0)] == [b.update(c) for c in (3.0, 8.0)]


def test_lagrange_rejects_negative_limit_and_unknown_optimizer() -> None:
    with pytest.raises(ValueError, match="cost_limit"):
        Lagrange(cost_limit=-1.0)
    with pytest.raises(ValueError, match="optimizer"):
        Lagrange(cost_limit=1.0, optimizer="rmsprop")


def test_pid_lagrange_matches_hand_computed_steps() -> None:
    pid = PIDLagrange(cost_limit=10.0, kp=0.5, ki=0.1, kd=0.2, ema_alpha=0.0,
                      derivative_delay=1, multiplier_init=0.0)
    # e=5: I=0.5, P=5, D=max(0, 15-0)=15 -> 2.5 + 0.5 + 3.0
    assert pid.update(15.0) == pytest.approx(6.0)
    # e=-8: I=max(0, 0.5-0.8)=0, P=-8, D=max(0, 2-15)=0 -> max(0, -4) = 0
    assert pid.update(2.0) == 0.0
    # e=2: I=0.2, P=2, D=max(0, 12-2)=10 -> 1 + 0.2 + 2
    assert pid.update(12.0) == pytest.approx(3.2)


def test_self_paced_thresholds_tighten_steps_down_only_when_satisfied() -> None:
    sched = SelfPacedThresholds(target=25.0, initial_exponent=8, num_thresholds=3, rule="tighten")
    assert sched.thresholds == [256.0, 128.0, 64.0, 32.0, 25.0]
    seen = [sched.update(c) for c in (300.0, 200.0, 100.0, 100.0, 50.0, 40.0, 30.0, 20.0, 500.0)]
    assert seen == [256.0, 128.0, 64.0, 64.0, 32.0, 32.0, 25.0, 25.0, 25.0]


def test_self_paced_thresholds_literal_is_eq_2_9() -> None:
    sched = SelfPacedThresholds(target=25.0, initial_exponent=8, num_thresholds=3, rule="literal")
    seen = [sched.update(c) for c in (300.0, 100.0, 20.0, 40.0, 130.0, 25.0)]
    assert seen == [256.0, 64.0, 25.0, 32.0, 128.0, 25.0]


def test_pid_and_schedule_state_dicts_round_trip() -> None:
    a = PIDLagrange(cost_limit=10.0, derivative_delay=3)
    for cost in (30.0, 5.0, 12.0):
        a.update(cost)
    b = PIDLagrange(cost_limit=10.0, derivative_delay=3)
    b.load_state_dict(a.state_dict())
    assert [a.update(c) for c in (20.0, 1.0)] == [b.update(c) for c in (20.0, 1.0)]
    s1 = SelfPacedThresholds(target=25.0)
    s1.update(100.0)
    s2 = SelfPacedThresholds(target=25.0)
    s2.load_state_dict(s1.state_dict())
    assert s2.current == s1.current == 128.0
    with pytest.raises(ValueError, match="thresholds"):
        SelfPacedThresholds(target=10.0).load_state_dict(s1.state_dict())


def test_self_paced_thresholds_drop_values_below_target_and_reject_bad_rule() -> None:
    assert SelfPacedThresholds(target=40.0, initial_exponent=6, num_thresholds=4).thresholds == [
        64.0, 40.0,
    ]
    with pytest.raises(ValueError, match="rule"):
        SelfPacedThresholds(target=1.0, rule="loosen")


def test_self_paced_thresholds_use_the_shared_solvers_schedule() -> None:
    """One implementation of Eqs. 2.8-2.12 for the toy problem and SP-PPO-Lag."""
    from solvers.threshold_schedule import ThresholdSchedule, threshold_schedule

    sched = SelfPacedThresholds(target=25.0)
    assert isinstance(sched, ThresholdSchedule)
    assert tuple(sched.thresholds) == threshold_schedule(8, 3, target=25.0)


def test_combined_advantage_is_lagrangian_rescaled() -> None:
    a_r, a_c = torch.tensor([1.0, -2.0]), torch.tensor([3.0, 1.0])
    torch.testing.assert_close(combined_advantage(a_r, a_c, 0.0), a_r)
    torch.testing.assert_close(combined_advantage(a_r, a_c, 1.0), torch.tensor([-1.0, -1.5]))
    with pytest.raises(ValueError, match="multiplier"):
        combined_advantage(a_r, a_c, -0.1)


def test_running_normalizer_matches_numpy_statistics() -> None:
    rng = np.random.default_rng(1)
    data = rng.normal(3.0, 2.0, size=(300, 2))
    norm = RunningNormalizer((2,), clip=100.0)
    for chunk in np.split(data, 3):
        norm.update(chunk)
    np.testing.assert_allclose(norm.mean, data.mean(0), rtol=1e-5)
    np.testing.assert_allclose(norm.var, data.var(0), rtol=1e-4)
    np.testing.assert_allclose(norm(data).mean(0), 0.0, atol=1e-4)
    assert np.abs(RunningNormalizer((2,), clip=1.0)(data)).max() <= 1.0


def test_merged_step_result_recovers_final_observation_and_cost_at_time_out() -> None:
    envs = make_vec_env({"id": "semdp/SpeedLimit-v0", "num_envs": 2}, seed=0)
    envs.reset(seed=0)
    zero = np.zeros((2, 1), dtype=np.float32)
    for _ in range(100):
        obs, rewards, term, trunc, infos = envs.step(zero)
        ended = term | trunc
        step = merged_step_result(obs, rewards, term, trunc, infos)
        costs, final = step.costs, step.final_observations()
    assert ended.all() and not term.any()  # time-out after 100 steps
    np.testing.assert_allclose(final[:, 1], 1.0)  # final obs has t/T = 1
    np.testing.assert_allclose(obs[:, 1], 0.0)  # returned obs is already the reset one
    assert costs.tolist() == [0.0, 0.0]


def test_speed_limit_env_costs_speeding_and_terminates_at_crash_speed() -> None:
    import gymnasium as gym

    env = gym.make("semdp/SpeedLimit-v0")
    obs, _ = env.reset(seed=3)
    speeds, costs = [], []
    terminated = False
    while not terminated:
        obs, reward, terminated, truncated, info = env.step(np.ones(1, dtype=np.float32))
        speeds.append(obs[0])
        costs.append(info["cost"])
        assert reward == pytest.approx(obs[0]) and not truncated
    assert speeds[-1] == pytest.approx(2.0)
    assert costs == [float(v > 1.0) for v in speeds]
    assert math.isclose(sum(costs), sum(v > 1.0 for v in speeds))


class _TimeCritic(torch.nn.Module):
    """V(obs) = 10 * (time feature): distinguishes a final observation from a reset one."""

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return 10.0 * obs[:, 1]


def test_rollout_bootstraps_time_outs_with_the_final_observation_and_not_terminations() -> None:
    from semdp.algos.ppo import PPO

    envs = make_vec_env({"id": "semdp/SpeedLimit-v0", "num_envs": 2}, seed=0)
    algo = PPO(envs, None, seed=0, steps_per_epoch=500, obs_normalize=False)
    algo.critic_r = _TimeCritic()
    algo.critic_c = _TimeCritic()
    algo.collect_rollout()
    b = algo.buffer
    timed_out = (b.episode_end == 1) & (b.terminated == 0)
    assert timed_out.any(axis=0).all()  # both envs hit the 100-step limit at least once
    np.testing.assert_allclose(b.next_values_r[timed_out], 10.0, rtol=1e-6)  # V(t/T = 1)
    np.testing.assert_allclose(b.next_values_c[timed_out], 10.0, rtol=1e-6)
    inner = b.episode_end[:-1] == 0
    np.testing.assert_allclose(b.next_values_r[:-1][inner], b.values_r[1:][inner])
    batch = algo.compute_batch()
    assert torch.isfinite(batch.adv_r).all()
    assert abs(float(batch.adv_c.mean())) < 1e-6  # cost advantages are centred
