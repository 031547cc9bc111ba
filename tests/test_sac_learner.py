"""SAC's round loop and learner process (docs/semdp.md, "The main job's loop"): the fused twin
critic and the shared replay buffer against their plain forms, the same numbers in a learner
process as inline, exact resume, and a learner process that ends with training -- also on
errors, on Ctrl-C and when it dies itself."""

from __future__ import annotations

import csv
import functools
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from hydra.errors import InstantiationException
from omegaconf import DictConfig, open_dict
from torch import nn

import semdp.algos.sac.algorithm as sac_module
from semdp.algos.sac import SAC
from semdp.algos.sac.learner import LearnerSettings, SACLearner
from semdp.algos.sac.learner_host import ProcessLearner
from semdp.algos.sac.replay import FIELDS, SharedReplayBuffer
from semdp.algos.sac.twin_q import FusedTwinQ
from semdp.cli.train import build_algorithm, run
from semdp.common.logger import TIMING_COLUMNS
from semdp.common.networks import SquashedGaussianActor, mlp
from solvers.workers import HelperError

#: The tiny SAC of tests/conftest.py with the round loop (16 env steps per round).
ROUNDS = ["algo.sync_every=16"]


def _rows(path: Path) -> list[dict[str, str]]:
    with (path / "progress.csv").open() as f:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(f)]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.exists() and stat.read_text().split()[2] == "Z")


@pytest.fixture
def hosts(monkeypatch: pytest.MonkeyPatch) -> list[ProcessLearner]:
    """Every ProcessLearner SAC starts during the test."""
    made: list[ProcessLearner] = []

    def record(*args, **kwargs) -> ProcessLearner:
        host = ProcessLearner(*args, **kwargs)
        made.append(host)
        return host

    monkeypatch.setattr(sac_module, "ProcessLearner", record)
    return made


def test_fused_twin_q_is_two_separate_networks() -> None:
    """Oracle: Q1 and Q2 as two plain ReLU MLPs drawn in that order from the same seed."""
    torch.manual_seed(3)
    fused = FusedTwinQ(7, 2, (32, 16))
    torch.manual_seed(3)
    q1_net, q2_net = (mlp(9, (32, 16), 1, "relu") for _ in range(2))
    obs, act = torch.randn(9, 7), torch.randn(9, 2)
    x = torch.cat([obs, act], dim=-1)
    expected = torch.stack([q1_net(x).squeeze(-1), q2_net(x).squeeze(-1)])
    torch.testing.assert_close(fused(obs, act), expected, rtol=0, atol=1e-6)
    frozen = [p.detach() for p in fused.parameters()]
    assert not fused(obs, act, frozen).requires_grad


def test_layer_norm_twin_q_normalises_each_networks_hidden_layers() -> None:
    """Oracle: each of the two networks written out as Linear -> LayerNorm (its own scale and
    shift) -> ReLU, from the fused weights."""
    torch.manual_seed(4)
    fused = FusedTwinQ(7, 2, (32, 16), layer_norm=True)
    with torch.no_grad():  # away from the initial scale 1 / shift 0, so that they matter
        for p in [*fused.ln_scales, *fused.ln_shifts]:
            p.add_(0.3 * torch.randn_like(p))
    obs, act = torch.randn(9, 7), torch.randn(9, 2)
    x = torch.cat([obs, act], dim=-1)
    expected = []
    for k in range(2):
        layer_norm = [nn.LayerNorm(h) for h in (32, 16)]
        with torch.no_grad():
            for i, ln in enumerate(layer_norm):
                ln.weight.copy_(fused.ln_scales[i][k, 0])
                ln.bias.copy_(fused.ln_shifts[i][k, 0])
        h = x @ fused.w_in[:, 32 * k:32 * (k + 1)] + fused.b_in[32 * k:32 * (k + 1)]
        h = torch.relu(layer_norm[0](h))
        h = torch.relu(layer_norm[1](h @ fused.weights[0][k] + fused.biases[0][k]))
        expected.append((h @ fused.weights[1][k] + fused.biases[1][k]).squeeze(-1))
    torch.testing.assert_close(fused(obs, act), torch.stack(expected), rtol=0, atol=1e-5)
    assert len(list(fused.parameters())) == len(list(FusedTwinQ(7, 2, (32, 16)).parameters())) + 4
    # at the initial scale and shift it is not the plain critic
    torch.manual_seed(4)
    plain, normed = FusedTwinQ(7, 2, (32, 16)), FusedTwinQ(7, 2, (32, 16), layer_norm=True)
    assert not torch.allclose(plain(obs, act), normed(obs, act))


def test_sac_trains_layer_norm_critics_through_the_learner() -> None:
    settings = LearnerSettings(5, 2, (8, 8), 3e-4, 1e-3, 0.99, 0.005, 16, 2, 1.0, True, -2.0,
                               1e-3, 0, critic_layer_norm=True)
    storage = {"obs": torch.randn(64, 5), "next_obs": torch.randn(64, 5),
               "actions": torch.rand(64, 2) * 2 - 1, "rewards": torch.randn(64),
               "terminated": torch.zeros(64)}
    learner = SACLearner(settings, storage)
    before = [p.detach().clone() for p in learner.critic.ln_scales]
    learner.run(4, 64)
    assert all(not torch.equal(b, p) for b, p in zip(before, learner.critic.ln_scales,
                                                     strict=True))
    assert learner.critic_target.layer_norm


def test_the_actors_one_sampler_draws_its_noise_like_normal_rsample() -> None:
    """Oracle: ``torch.distributions.Normal(mean, std).rsample()`` from the same seed, squashed,
    and its log-density with the tanh correction written out; the mode is tanh(mean)."""
    torch.manual_seed(0)
    actor = SquashedGaussianActor(7, 2, (16, 16))
    obs = torch.randn(5, 7) * 3.0
    with torch.inference_mode():
        mean, raw = actor.head(obs)
        std = (actor.LOG_STD_MIN + 0.5 * (actor.LOG_STD_MAX - actor.LOG_STD_MIN)
               * (torch.tanh(raw) + 1.0)).exp()
        torch.manual_seed(11)
        u = torch.distributions.Normal(mean, std).rsample()
        after_rsample = torch.rand(3)
        torch.manual_seed(11)
        action, log_prob = actor(obs)
        after_forward = torch.rand(3)
        mode, _ = actor(obs, deterministic=True)
    assert torch.equal(action, torch.tanh(u))
    assert torch.equal(after_forward, after_rsample)  # the generator advanced alike
    expected = (torch.distributions.Normal(mean, std).log_prob(u)
                - torch.log(1 - torch.tanh(u) ** 2)).sum(-1)
    torch.testing.assert_close(log_prob, expected, rtol=1e-4, atol=1e-4)
    assert torch.equal(mode, torch.tanh(mean))
    torch.manual_seed(12)
    assert not torch.equal(actor(obs)[0], action)


@pytest.mark.parametrize(("policy_steps", "actor_steps"), [(0, 6), (1, 3), (3, 9)])
def test_policy_steps_sets_the_actor_updates_per_delay(policy_steps: int,
                                                         actor_steps: int) -> None:
    """6 critic updates at policy_frequency 2: CleanRL's 2 actor (and temperature) updates every
    second critic update (6), TD3's one (3), or any count."""
    n = 64
    storage = {"obs": torch.randn(n, 5), "next_obs": torch.randn(n, 5),
               "actions": torch.rand(n, 2) * 2 - 1, "rewards": torch.randn(n),
               "terminated": torch.zeros(n)}
    settings = LearnerSettings(5, 2, (8, 8), 3e-4, 1e-3, 0.99, 0.005, 16, 2, 1.0, True, -2.0,
                               1e-3, 0, policy_steps=policy_steps)
    learner = SACLearner(settings, storage)
    out = learner.run(6, n)
    assert learner.updates == 6 and len(out["loss_q"]) == 6 and len(out["loss_pi"]) == 3
    steps = {int(state["step"]) for state in learner.actor_optimizer.state.values()}
    assert steps == {actor_steps}
    assert {int(s["step"]) for s in learner.alpha_optimizer.state.values()} == {actor_steps}
    assert {int(s["step"]) for s in learner.critic_optimizer.state.values()} == {6}


def test_sac_rejects_policy_steps_below_one(tiny_train: Callable[..., DictConfig]) -> None:
    with pytest.raises(InstantiationException, match="policy_steps must be >= 1"):
        build_algorithm(tiny_train("sac", "algo.policy_steps=0"))


@pytest.mark.parametrize("shared", [False, True])
def test_replay_buffer_is_a_ring_of_the_latest_rows(shared: bool) -> None:
    """Oracle: transition number ``t`` (counted over all batches) sits in row ``t % capacity``
    while it is among the latest ``capacity`` ones."""
    ours = SharedReplayBuffer(10, 3, 2, shared=shared)
    rng = np.random.default_rng(0)
    stream: dict[str, list[np.ndarray]] = {name: [] for name in FIELDS}
    for n in (4, 3, 5, 12, 1):  # wraps around, and one batch larger than the capacity
        batch = {"obs": rng.normal(size=(n, 3)), "actions": rng.normal(size=(n, 2)),
                 "rewards": rng.normal(size=n), "costs": rng.normal(size=n),
                 "next_obs": rng.normal(size=(n, 3)), "terminated": rng.integers(0, 2, n),
                 "horizons": rng.integers(1, 4, n)}
        ours.add_batch(batch["obs"], batch["actions"], batch["rewards"], batch["costs"],
                       batch["next_obs"], batch["terminated"], batch["horizons"])
        for name in FIELDS:
            stream[name].extend(batch[name].astype(np.float32))
        total = len(stream["obs"])
        assert (ours.pos, ours.size) == (total % 10, min(total, 10))
        for t in range(max(0, total - 10), total):
            for name in FIELDS:
                np.testing.assert_array_equal(ours.arrays[name][t % 10], stream[name][t])
                np.testing.assert_array_equal(ours.tensors[name][t % 10].numpy(),
                                              stream[name][t])
    state = ours.state_dict()
    again = SharedReplayBuffer(10, 3, 2)
    again.load_state_dict(state)
    np.testing.assert_array_equal(again.arrays["obs"], ours.arrays["obs"])
    np.testing.assert_array_equal(again.arrays["horizons"], ours.arrays["horizons"])
    del state["horizons"]  # a checkpoint from before n-step rows: one-step horizons
    again.load_state_dict(state)
    np.testing.assert_array_equal(again.arrays["horizons"], np.ones(10, np.float32))
    pos = ours.pos
    ours.add_batch(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(2), np.zeros(2), np.zeros((2, 3)),
                   np.zeros(2))  # no horizons given: one-step rows
    np.testing.assert_array_equal(ours.arrays["horizons"][[pos, (pos + 1) % 10]], [1.0, 1.0])


def test_learner_process_gives_the_inline_numbers(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, hosts: list[ProcessLearner]
) -> None:
    inline = run(tiny_train("sac", *ROUNDS, "algo.learner=inline"), tmp_path / "inline")
    process = run(tiny_train("sac", *ROUNDS, "algo.learner=process"), tmp_path / "process")
    assert len(hosts) == 1 and not _alive(hosts[0].helper.pid)
    a, b = _rows(tmp_path / "inline"), _rows(tmp_path / "process")
    assert a == b and a[-1]["loss_q"] != "" and a[-1]["alpha"] != "1.0"
    assert inline["eval"] == process["eval"]


#: 3-step rows (semdp/algos/sac/n_step.py) in epochs of 80 vector steps, which end inside the
#: 100-step episodes: windows are pending at every checkpoint.
N_STEP = ("algo.n_step=3", "budget.steps_per_epoch=160", "total_steps=640")


@pytest.mark.parametrize("extra", [(), N_STEP], ids=["one-step", "n-step"])
def test_round_loop_resumes_exactly_after_a_crash(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    hosts: list[ProcessLearner], crash_in_epoch_3: Callable[[type], Callable[..., Any]],
    extra: tuple[str, ...],
) -> None:
    config = functools.partial(tiny_train, "sac", *ROUNDS, "algo.learner=process",
                               "checkpoint_every=1", *extra)
    reference = run(config(), tmp_path / "ref")
    original = crash_in_epoch_3(SAC)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run(config(), tmp_path / "crashed")
    assert not _alive(hosts[-1].helper.pid)  # the learner process ended with the error
    monkeypatch.setattr(SAC, "train_epoch", original)
    resumed_cfg = config()
    with open_dict(resumed_cfg):
        resumed_cfg.resume = str(tmp_path / "crashed")
    resumed = run(resumed_cfg, tmp_path / "ignored")
    assert _rows(tmp_path / "crashed") == _rows(tmp_path / "ref")
    assert resumed["eval"] == reference["eval"] and resumed["status"] == "completed"
    assert all(not _alive(h.helper.pid) for h in hosts)


def test_keyboard_interrupt_stops_the_learner_process(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    hosts: list[ProcessLearner],
) -> None:
    algo = build_algorithm(tiny_train("sac", *ROUNDS, "algo.learner=process"))
    step = algo.envs.step
    calls = {"n": 0}

    def interrupted(actions):  # Ctrl-C while collecting, with a round of updates running
        calls["n"] += 1
        if calls["n"] == 90:
            raise KeyboardInterrupt
        return step(actions)

    monkeypatch.setattr(algo.envs, "step", interrupted)
    with pytest.raises(KeyboardInterrupt):
        algo.learn(total_steps=800, run_dir=tmp_path)
    assert len(hosts) == 1 and algo._host is None
    assert not _alive(hosts[0].helper.pid)


def test_a_dead_learner_process_fails_the_run_instead_of_hanging(
    tiny_train: Callable[..., DictConfig], tmp_path: Path, hosts: list[ProcessLearner],
) -> None:
    algo = build_algorithm(tiny_train("sac", *ROUNDS, "algo.learner=process"))
    algo.train_epoch()  # learning starts: the process runs rounds
    os.kill(hosts[0].helper.pid, signal.SIGKILL)
    start = time.monotonic()
    with pytest.raises(HelperError, match=r"semdp-learner .* died \(killed by SIGKILL\)"):
        algo.train_epoch()
    assert time.monotonic() - start < 30
    algo.close(keep_state=False)


def test_ctrl_c_on_semdp_train_ends_training_and_learner(tmp_path: Path) -> None:
    """A real SIGINT to ``semdp-train`` (as a terminal's Ctrl-C): the run is recorded as failed
    and no learner process is left behind."""
    cmd = [sys.executable, "-m", "semdp.cli.train", "algo=sac", "env=speed_limit", "budget=ci",
           "total_steps=200000", "budget.steps_per_epoch=400", "algo.learning_starts=100",
           "algo.batch_size=32", "algo.hidden_sizes=[16,16]", "algo.buffer_size=5000",
           "algo.learner=process", "tensorboard=false", f"hydra.run.dir={tmp_path}"]
    # as from a terminal: SIGINT handled, even when pytest itself runs as a background job
    # (a non-interactive shell starts those with SIGINT ignored, which children inherit)
    train = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))

    def learners() -> list[int]:
        found = []
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
                cmdline = (stat.parent / "cmdline").read_bytes()
            except OSError:
                continue
            if int(fields[1]) == train.pid and b"semdp.algos.sac.learner_process" in cmdline:
                found.append(int(stat.parent.name))
        return found

    deadline = time.monotonic() + 60
    while not learners() and time.monotonic() < deadline and train.poll() is None:
        time.sleep(0.2)
    pids = learners()
    assert pids, "the learner process never started"
    time.sleep(1.0)  # inside the round loop
    train.send_signal(signal.SIGINT)
    _, err = train.communicate(timeout=60)
    assert train.returncode != 0
    assert b"KeyboardInterrupt" in err
    for pid in pids:
        for _ in range(50):
            if not _alive(pid):
                break
            time.sleep(0.1)
        assert not _alive(pid)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["status"] == "failed" and "KeyboardInterrupt" in metrics["error"]
