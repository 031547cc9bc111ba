"""The on-policy speed-ups change no number: fast stepping equals gymnasium's SyncVectorEnv, a
rollout split with the helper process equals one process's, critics regressed in the helper
equal the trainer's, whatever the mode a seeded run writes the same ``progress.csv``, resumes
are exact, and every helper process is gone when ``learn`` returns."""

from __future__ import annotations

import csv
import multiprocessing as mp
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import DictConfig, open_dict

from semdp.algos.critic_regression import CriticTargets, regress_critics
from semdp.algos.helpers.critic_helper import CriticWorker
from semdp.cli.train import run
from semdp.common.logger import TIMING_COLUMNS
from semdp.common.networks import ValueCritic
from semdp.common.vector_stepping import MergedInfoStepper, VectorStepper, success_flags
from semdp.envs import make_vec_env
from solvers.workers import fork_available

pytestmark = pytest.mark.skipif(not fork_available(), reason="helpers need fork")

SYNC = ("algo.vectorization=sync", "algo.parallel_critics=false")
ASYNC = ("algo.vectorization=async", "algo.parallel_critics=true")
AUTO = ("algo.vectorization=auto", "algo.parallel_critics=auto")
#: Columns that record which helpers ran (they differ between the ways; no number does).
PATH_COLUMNS = ("rollout_helper", "critic_helper")


def _rows(path: Path) -> list[dict[str, str]]:
    with (path / "progress.csv").open() as f:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS and k not in PATH_COLUMNS}
                for r in csv.DictReader(f)]


def _actions(rng: np.random.Generator, envs) -> np.ndarray:
    space = envs.single_action_space
    shape = (envs.num_envs, *space.shape)
    return rng.uniform(space.low, space.high, shape).astype(space.dtype)


@pytest.mark.parametrize("env_id", ["semdp/SpeedLimit-v0", "sims/SafetyPointButton1-v0"])
def test_vector_stepper_matches_sync_vector_env_step(env_id: str) -> None:
    cfg = {"id": env_id, "num_envs": 3, "kwargs": {"max_episode_steps": 40}}
    ref, fast = make_vec_env(cfg, seed=0), make_vec_env(cfg, seed=0)
    ref.reset(seed=5)
    fast.reset(seed=5)
    stepper, merged = VectorStepper(fast), MergedInfoStepper(ref)
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(130):
        actions = _actions(rng, ref)
        expected = merged.step(actions)  # SyncVectorEnv.step, read from its merged infos
        step = stepper.step(actions)
        np.testing.assert_array_equal(step.obs, expected.obs)
        np.testing.assert_array_equal(step.rewards, expected.rewards)
        np.testing.assert_array_equal(step.terminated, expected.terminated)
        np.testing.assert_array_equal(step.truncated, expected.truncated)
        np.testing.assert_array_equal(step.costs, expected.costs)
        np.testing.assert_array_equal(step.final_observations(), expected.final_observations())
        assert step.final_infos == expected.final_infos
        assert sorted(step.final_obs) == list(np.flatnonzero(expected.ended))
        ends += int(expected.ended.sum())
    assert ends >= 9


def test_success_flags_follow_gymnasiums_merged_final_info() -> None:
    assert success_flags({0: {"cost": 0.0}, 2: {}}) == {0: None, 2: None}
    assert success_flags({0: {"success": True}, 2: {}}) == {0: 1.0, 2: 0.0}
    assert success_flags({1: {"is_success": 0.0}}) == {1: 0.0}


@pytest.mark.parametrize("local", [1, 2])
def test_split_rollout_equals_one_process_and_its_envs_come_back(local: int) -> None:
    from semdp.algos.helpers.rollout_helper import RolloutHelper, merge_parts
    from semdp.algos.ppo import PPO
    from semdp.algos.rollout import noise_for, roll_part

    cfg = {"id": "sims/SafetyCarGoal2-v0", "num_envs": 3, "kwargs": {"max_episode_steps": 25}}
    torch.manual_seed(0)
    algo = PPO(make_vec_env(cfg, seed=0), None, seed=1, steps_per_epoch=120)
    here = make_vec_env(cfg, seed=0)
    here.reset(seed=1)
    obs = algo._obs.copy()
    helper = RolloutHelper(algo.envs, range(local, 3), algo.actor, algo.normalizer,
                           algo.to_env_action)
    try:
        for _ in range(2):
            noise = noise_for(40, 3, algo.act_dim)
            whole = roll_part(algo.actor, algo.normalizer, algo.to_env_action,
                              VectorStepper(here), range(3), 3, noise, obs)
            helper.start(algo.actor, algo.normalizer, noise[:, local:], obs[local:])
            mine = roll_part(algo.actor, algo.normalizer, algo.to_env_action,
                             VectorStepper(algo.envs, range(local)), range(local), 3,
                             noise[:, :local], obs[:local])
            split = merge_parts(mine, helper.result())
            for name in ("raw_obs", "obs", "actions", "log_probs", "rewards", "costs",
                         "terminated", "truncated", "last_obs"):
                np.testing.assert_array_equal(getattr(split, name), getattr(whole, name))
            assert split.final_obs.keys() == whole.final_obs.keys() and whole.final_obs
            obs = whole.last_obs
            with torch.no_grad():  # the next epoch's policy differs
                algo.actor.log_std.add_(0.1)
        restored = pickle.loads(pickle.dumps(helper.snapshot()))  # a checkpoint's round trip
        pickle.dumps(here)  # ... and the same one here
        actions = _actions(np.random.default_rng(3), here)
        expected = VectorStepper(here).step(actions).obs
        np.testing.assert_array_equal(VectorStepper(restored).step(actions).obs, expected)
        gathered = helper.gather()
        assert gathered is algo.envs
        np.testing.assert_array_equal(VectorStepper(gathered).step(actions).obs, expected)
    finally:
        helper.close()
    with pytest.raises(RuntimeError):
        helper.start(algo.actor, algo.normalizer, noise[:, local:], obs[local:])


def test_critic_worker_regresses_bit_identically_and_can_be_cancelled() -> None:
    torch.manual_seed(0)
    nets = [ValueCritic(5, (8, 8)) for _ in range(2)]
    copies = [ValueCritic(5, (8, 8)) for _ in range(2)]
    for net, copy in zip(nets, copies, strict=True):
        copy.load_state_dict(net.state_dict())
    opt = torch.optim.Adam([p for n in nets for p in n.parameters()], lr=1e-2, foreach=True)
    opt_copy = torch.optim.Adam([p for n in copies for p in n.parameters()], lr=1e-2,
                                foreach=True)
    targets = CriticTargets(torch.randn(64, 5), torch.randn(64), torch.randn(64))
    perms = [torch.randperm(64) for _ in range(3)]
    worker = CriticWorker(*copies, opt_copy, regress_critics)
    try:
        for _ in range(2):  # the second round starts from trained Adam state
            worker.submit(*copies, opt_copy, targets, perms, 16, 1e-3, 0.5)
            remote = worker.result(*copies, opt_copy)
            local = regress_critics(*nets, opt, targets, perms, 16, 1e-3, 0.5)
            assert remote == local
            for net, copy in zip(nets, copies, strict=True):
                for p, q in zip(net.parameters(), copy.parameters(), strict=True):
                    assert torch.equal(p, q)
        worker.submit(*copies, opt_copy, targets, perms * 200, 1, 1e-3, 0.5)
        worker.cancel()
        with pytest.raises(RuntimeError, match="no critic regression"):
            worker.result(*copies, opt_copy)
    finally:
        worker.close()


@pytest.mark.parametrize("algo", ["ppo", "sp_ppo_lag", "trpo_lag", "cpo"])
def test_helper_processes_change_no_number(
    algo: str, tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    run(tiny_train(algo, *SYNC), tmp_path / "sync")
    run(tiny_train(algo, *ASYNC), tmp_path / "async")
    assert _rows(tmp_path / "sync") == _rows(tmp_path / "async")
    assert not mp.active_children()  # learn() stopped its helpers


def test_ppo_early_stop_discards_the_speculative_critic_regression(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    stop_early = "algo.target_kl=1e-9"  # the KL check stops after the first pass
    run(tiny_train("ppo_lag", stop_early, *SYNC), tmp_path / "sync")
    run(tiny_train("ppo_lag", stop_early, *ASYNC), tmp_path / "async")
    rows = _rows(tmp_path / "async")
    assert {r["update_passes"] for r in rows} == {"1"}
    assert _rows(tmp_path / "sync") == rows


def test_async_resume_matches_the_uninterrupted_sync_run(
    tiny_train: Callable[..., DictConfig], tmp_path: Path
) -> None:
    pymunk = ("env=point_goal1", "env.num_envs=2", "+env.kwargs.max_episode_steps=150",
              "algo.lr_decay=false")  # the learning rate schedule depends on total_steps
    run(tiny_train("ppo_lag", *pymunk, *SYNC), tmp_path / "ref")
    first = tiny_train("ppo_lag", *pymunk, *ASYNC, "total_steps=400")
    run(first, tmp_path / "split")
    resumed = tiny_train("ppo_lag", *pymunk, *ASYNC)
    with open_dict(resumed):
        resumed.resume = str(tmp_path / "split")
    saved = tmp_path / "split" / "config.yaml"
    saved.write_text(saved.read_text().replace("total_steps: 400", "total_steps: 800"))
    run(resumed, tmp_path / "ignored")
    assert _rows(tmp_path / "split") == _rows(tmp_path / "ref")
    assert not mp.active_children()


def test_auto_mode_probes_both_ways_and_keeps_cheap_envs_in_the_trainer(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from semdp.algos.helpers import modes as helpers
    from semdp.algos.helpers import rollout_helper
    from semdp.cli.train import build_algorithm

    monkeypatch.setattr(helpers, "_cpus", lambda: 2)  # two usable cores, whatever the machine
    monkeypatch.setattr(helpers, "idle_core", lambda: False)  # a busy machine: probe both
    monkeypatch.setattr(rollout_helper, "ASYNC_MIN_STEP_S", 1.0)  # every env counts as cheap
    cheap = build_algorithm(tiny_train("ppo", *AUTO))
    critics = []
    for _ in range(3):
        cheap.train_epoch()
        assert not cheap.envs_in_helper
        critics.append(cheap.critics_in_helper)
    assert critics[:2] == [False, True]  # the first two updates measure both ways
    cheap.close_helpers()
    monkeypatch.setattr(rollout_helper, "ASYNC_MIN_STEP_S", 0.0)  # every env counts as slow
    run(tiny_train("ppo", *AUTO), tmp_path / "auto")
    run(tiny_train("ppo", *SYNC), tmp_path / "sync")
    assert _rows(tmp_path / "auto") == _rows(tmp_path / "sync")
    probing = build_algorithm(tiny_train("ppo", *AUTO))
    used = []
    for _ in range(4):
        probing.train_epoch()
        used.append((probing.envs_in_helper, probing.critics_in_helper))
    assert used[:2] == [(False, False), (True, True)]  # each way measured once, then the faster
    probing.close_helpers()
    # a core idle at the start: the helpers from the first epoch; the cheap envs come back
    monkeypatch.setattr(helpers, "idle_core", lambda: True)
    quiet = build_algorithm(tiny_train("ppo", *AUTO))
    quiet.train_epoch()
    assert quiet.envs_in_helper and quiet.critics_in_helper
    quiet.close_helpers()
    monkeypatch.setattr(rollout_helper, "ASYNC_MIN_STEP_S", 1.0)
    cheap_quiet = build_algorithm(tiny_train("ppo", *AUTO))
    for _ in range(2):
        cheap_quiet.train_epoch()
    assert not cheap_quiet.envs_in_helper and cheap_quiet.critics_in_helper
    cheap_quiet.close_helpers()
    run(tiny_train("ppo", *AUTO), tmp_path / "quiet")
    assert _rows(tmp_path / "quiet") == _rows(tmp_path / "sync")
    assert not mp.active_children()


def test_vector_env_subclasses_keep_their_own_step() -> None:
    """A SyncVectorEnv subclass is stepped through its own ``step`` (it may do more, as the
    SEMDP lockstep env, built like a SyncVectorEnv, does)."""
    import functools

    import gymnasium as gym

    from semdp.common.vector_stepping import stepper_for
    from semdp.envs import make_env

    class Counting(gym.vector.SyncVectorEnv):
        calls = 0

        def step(self, actions):
            Counting.calls += 1
            return super().step(actions)

    factory = functools.partial(make_env, "semdp/SpeedLimit-v0")
    envs = Counting([factory] * 2, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    envs.reset(seed=0)
    stepper = stepper_for(envs)
    assert isinstance(stepper, MergedInfoStepper)
    stepper.step(_actions(np.random.default_rng(0), envs))
    assert Counting.calls == 1
    from semdp.algos.ppo import PPO
    from semdp.algos.speedups import HelperRunners

    with pytest.raises(ValueError, match="SyncVectorEnv, got Counting"):
        PPO(envs, None, seed=0, steps_per_epoch=64, runners=HelperRunners("async", False))
