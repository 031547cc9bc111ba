"""The lockstep SEMDP vector env (thesis Alg. 2 for several envs at once): the same steps as
gymnasium's SyncVectorEnv, one batched follower forward per low-level step, pickling, and the
wrapper's window phases."""

from __future__ import annotations

import pickle
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest
import torch
from omegaconf import DictConfig, open_dict

from semdp.embedded.follower import PolicyFollower, ProportionalFollower
from semdp.embedded.follower_batch import FollowerBatch, NumpyMLP
from semdp.embedded.vector import LockstepVectorEnv
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.envs import make_vec_env

LOCKSTEP = "semdp.embedded.vector.LockstepVectorEnv"


def _env_node(compose_train: Callable[..., DictConfig], env: str, n: int,
              vector: str | None) -> DictConfig:
    cfg = compose_train("experiment=semdp", f"env={env}", f"env.num_envs={n}",
                        "++env.kwargs.max_episode_steps=60")
    with open_dict(cfg):
        cfg.env.vector = vector
    return cfg.env


def _pair(compose_train: Callable[..., DictConfig], env: str, n: int = 3):
    """The same SEMDP envs under gymnasium's SyncVectorEnv and under the lockstep env."""
    return (make_vec_env(_env_node(compose_train, env, n, None), seed=0),
            make_vec_env(_env_node(compose_train, env, n, LOCKSTEP), seed=0))


def _same_step(a: tuple, b: tuple, atol: float = 0.0) -> None:
    for x, y in zip(a[:4], b[:4], strict=True):
        np.testing.assert_allclose(x, y, atol=atol, rtol=0)
    assert sorted(a[4]) == sorted(b[4])
    if "cost" in a[4]:  # absent when every env ended: the merged infos are the resets' then
        np.testing.assert_allclose(a[4]["cost"], b[4]["cost"], atol=atol)
    if "final_obs" in a[4]:
        np.testing.assert_allclose(a[4]["final_info"]["cost"], b[4]["final_info"]["cost"],
                                   atol=atol)
        np.testing.assert_array_equal(a[4]["_final_obs"], b[4]["_final_obs"])
        for i in np.flatnonzero(a[4]["_final_obs"]):
            np.testing.assert_allclose(a[4]["final_obs"][i], b[4]["final_obs"][i], atol=atol)


def test_lockstep_equals_sync_vector_env_step_for_step(
    compose_train: Callable[..., DictConfig],
) -> None:
    # Mass: the P-controller acts env by env, so the lockstep order must give identical steps,
    # autoreset (6 high-level steps per 60-step episode) and infos included.
    sync, lockstep = _pair(compose_train, "semdp_mass_push1")
    assert isinstance(lockstep, LockstepVectorEnv) and lockstep.lockstep
    assert not lockstep.followers.batched
    np.testing.assert_array_equal(sync.reset(seed=4)[0], lockstep.reset(seed=4)[0])
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(14):
        actions = rng.uniform(-1, 1, size=(3, 2)).astype(np.float32)
        a, b = sync.step(actions), lockstep.step(actions)
        _same_step(a, b)
        ended += int(np.logical_or(a[2], a[3]).sum())
    assert ended == 6  # two episodes per env ended, and were reset, inside the window loop


def test_lockstep_point_followers_act_in_one_forward_close_to_torch(
    compose_train: Callable[..., DictConfig],
) -> None:
    sync, lockstep = _pair(compose_train, "semdp_point_push1", n=2)
    assert lockstep.followers.batched
    np.testing.assert_array_equal(sync.reset(seed=1)[0], lockstep.reset(seed=1)[0])
    actions = np.array([[0.5, -0.2], [-0.3, 0.8]], dtype=np.float32)
    # The NumPy forward rounds differently from torch's (1e-7): one step stays close.
    _same_step(sync.step(actions), lockstep.step(actions), atol=1e-4)


def test_numpy_mlp_matches_the_torch_follower_policy() -> None:
    follower = PolicyFollower("point.pt")
    mlp = NumpyMLP(follower.actor)
    x = np.random.default_rng(0).normal(size=(5, 14)).astype(np.float32)
    with torch.no_grad():
        expected = follower.actor(torch.as_tensor(x)).numpy()
    # float32 both ways; the BLAS kernels (numpy's OpenBLAS, torch's MKL) sum in their own
    # order, a few float32 ulps apart (1.5e-6 on an AVX-512 machine)
    np.testing.assert_allclose(mlp(x.copy()), expected, rtol=1e-5, atol=1e-5)


def test_batched_network_inputs_are_each_followers_own_bit_for_bit() -> None:
    """The stacked inputs (one array operation per part) against each follower's
    ``network_input``, on random observations, positions, headings and targets."""
    followers = [PolicyFollower("point.pt") for _ in range(4)]
    obs_slices = {"accelerometer": slice(0, 3), "velocimeter": slice(3, 6),
                  "gyro": slice(6, 9), "magnetometer": slice(9, 12), "lidar": slice(12, 28)}
    rng = np.random.default_rng(5)
    mean, std = rng.normal(size=14).astype(np.float32), rng.uniform(0.5, 2, 14).astype(np.float32)
    for f in followers:  # the committed follower has none: normalise and clip as one that has
        f.bind(obs_slices)
        f.obs_mean, f.obs_std, f.obs_clip = mean, std, 2.5
    batch = FollowerBatch(followers)
    for _ in range(50):
        inputs = [(rng.normal(scale=3.0, size=28), rng.uniform(-2, 2, size=2),
                   float(rng.uniform(-10, 10)), rng.uniform(-2, 2, size=2)) for _ in range(4)]
        indices = [3, 0, 2] if rng.random() < 0.5 else [0, 1, 2, 3]
        chosen = [inputs[i] for i in indices]
        expected = np.stack([followers[i].network_input(*args)
                             for i, args in zip(indices, chosen, strict=True)])
        got = batch.network_inputs(indices, chosen)
        assert got.dtype == expected.dtype == np.float32
        np.testing.assert_array_equal(got, expected)
    with pytest.raises(RuntimeError, match="bind"):
        FollowerBatch([PolicyFollower("point.pt")]).network_inputs([0], inputs[:1])


def test_follower_batch_falls_back_to_one_by_one_for_mixed_followers() -> None:
    mixed = FollowerBatch([PolicyFollower("point.pt"), ProportionalFollower(gain=8.0)])
    assert not mixed.batched
    with pytest.raises(ValueError):
        FollowerBatch([])


def test_lockstep_env_pickles_and_continues_identically(
    compose_train: Callable[..., DictConfig],
) -> None:
    _, lockstep = _pair(compose_train, "semdp_point_push1", n=2)
    lockstep.reset(seed=2)
    actions = np.array([[0.2, 0.1], [-0.6, 0.4]], dtype=np.float32)
    lockstep.step(actions)
    copy = pickle.loads(pickle.dumps(lockstep))
    for _ in range(3):
        _same_step(lockstep.step(actions), copy.step(actions))


def test_lockstep_falls_back_to_sync_stepping_under_foreign_wrappers(
    compose_train: Callable[..., DictConfig],
) -> None:
    cfg = compose_train("experiment=semdp", "env=semdp_mass_push1", "env.num_envs=2")
    fns = [lambda: gym.wrappers.ClipReward(gym.make(cfg.env.id), -1.0, 1.0)] * 2
    env = LockstepVectorEnv(fns)
    assert not env.lockstep


def test_window_phases_are_the_step(compose_train: Callable[..., DictConfig]) -> None:
    """``step`` = ``begin_window`` + k x (``tracking_target``, follower, ``low_level_step``) +
    ``end_window``: driving the phases by hand gives the same step as ``step``."""
    node = _env_node(compose_train, "semdp_mass_push1", 1, None)
    a, b = (make_vec_env(node, seed=0).envs[0].env for _ in range(2))
    assert isinstance(a, SafetyEmbeddedEnv)
    a.reset(seed=9)
    b.reset(seed=9)
    action = np.array([0.7, -0.4])
    expected = a.step(action)
    window = b.begin_window(action)
    while True:
        low = b.follower.act(*b.tracking_target(window))
        if b.low_level_step(window, low):
            break
    got = b.end_window(window)
    np.testing.assert_array_equal(expected[0], got[0])
    assert expected[1:4] == got[1:4] and expected[4]["cost"] == got[4]["cost"]
    assert got[4]["low_level_steps"] == 10
