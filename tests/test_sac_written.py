"""The SAC learner's ``gradients="written"`` kernel (semdp/algos/kernels/sac_written.py) against
autograd, the oracle: the gradients of each loss bit for bit on random inputs, and whole learners
run update by update to the same parameters, optimiser states, temperatures and logs."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import pytest
import torch
from hydra.errors import InstantiationException
from omegaconf import DictConfig

from semdp.algos.kernels import sac_written
from semdp.algos.sac.learner import LOG_KEYS, LearnerSettings, SACLearner
from semdp.algos.sac.twin_q import FusedTwinQ
from semdp.cli.train import _config_differences, build_algorithm
from semdp.common.networks import SquashedGaussianActor, forward_mlp, mlp
from semdp.common.optim import LeanAdam


def _storage(n: int, obs_dim: int, act_dim: int, n_step: bool = False) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(n + obs_dim)
    out = {"obs": torch.randn(n, obs_dim, generator=g) * 2.0,
           "next_obs": torch.randn(n, obs_dim, generator=g) * 2.0,
           "actions": torch.rand(n, act_dim, generator=g) * 2 - 1,
           "rewards": torch.randn(n, generator=g),
           "terminated": (torch.rand(n, generator=g) < 0.1).float()}
    if n_step:
        out["horizons"] = torch.randint(1, 4, (n,), generator=g).float()
    return out


def _equal_learners(a: SACLearner, b: SACLearner) -> None:
    for name in ("actor", "critic", "critic_target"):
        for (key, x), y in zip(getattr(a, name).named_parameters(),
                               getattr(b, name).parameters(), strict=True):
            assert torch.equal(x, y), f"{name}.{key}"
    assert torch.equal(a.log_alpha, b.log_alpha)
    for name in ("actor_optimizer", "critic_optimizer", "alpha_optimizer"):
        sa, sb = getattr(a, name).state_dict()["state"], getattr(b, name).state_dict()["state"]
        assert sa.keys() == sb.keys()
        for key in sa:
            for field in ("step", "exp_avg", "exp_avg_sq"):
                assert torch.equal(sa[key][field], sb[key][field]), f"{name} {key} {field}"
    assert torch.equal(a.generator.get_state(), b.generator.get_state())


SETTINGS = [
    # the main job's networks (PointPush1's high-level observation, 2-D subgoal)
    LearnerSettings(60, 2, (128, 128), 3e-4, 1e-3, 0.99, 0.005, 128, 2, 1.0, True, -2.0, 1e-3, 0),
    # three hidden layers of unequal widths, TD3's delayed actor, a batch not a power of two
    LearnerSettings(7, 3, (24, 16, 8), 3e-4, 1e-3, 0.9, 0.01, 20, 2, 0.5, True, -3.0, 1e-3, 5,
                    policy_steps=1),
    # a fixed temperature, policy delay 3, n-step rows
    LearnerSettings(5, 2, (8, 8), 1e-3, 1e-3, 0.99, 0.005, 16, 3, 0.2, False, -2.0, 1e-3, 9,
                    n_step=3),
]


@pytest.mark.parametrize("settings", SETTINGS, ids=["main_job", "three_layers", "fixed_alpha"])
def test_written_learner_runs_autograds_updates_bit_for_bit(settings: LearnerSettings) -> None:
    storage = _storage(400, settings.obs_dim, settings.act_dim, n_step=settings.n_step > 1)
    torch.manual_seed(3)
    plain = SACLearner(settings, storage)
    torch.manual_seed(3)
    written = SACLearner(dataclasses.replace(settings, gradients="written"), storage)
    _equal_learners(plain, written)
    for size in (50, 400, 400):
        expected, got = plain.run(24, size), written.run(24, size)
        for key in (*LOG_KEYS, "log_alpha"):
            assert got[key] == expected[key], key
        _equal_learners(plain, written)
    assert plain.updates == written.updates == 72


def _autograd_grads(loss: torch.Tensor, params: list[torch.Tensor]) -> list[torch.Tensor]:
    for p in params:
        p.grad = None
    loss.backward()
    return [p.grad for p in params]


@pytest.mark.parametrize("seed", range(6))
def test_critic_and_actor_gradients_equal_autograds(seed: int) -> None:
    torch.manual_seed(seed)
    obs_dim, act_dim, hidden, batch = 9, 2, (32, 16), 48
    critic = FusedTwinQ(obs_dim, act_dim, hidden)
    actor = SquashedGaussianActor(obs_dim, act_dim, hidden)
    with torch.no_grad():  # away from the initial weights (larger log-std spread, some ReLUs off)
        for p in [*critic.parameters(), *actor.parameters()]:
            p.add_(torch.randn_like(p) * 0.3)
    obs, actions = torch.randn(batch, obs_dim) * 3.0, torch.rand(batch, act_dim) * 2 - 1
    target, noise, alpha = torch.randn(batch) * 5.0, torch.randn(batch, act_dim), torch.tensor(0.3)
    params = list(critic.parameters())
    # critic loss (SACLearner._update_autograd's expression)
    q = critic(obs, actions)
    loss_q = (q - target).square().mean(1).sum()
    expected = _autograd_grads(loss_q, params)
    with torch.no_grad():
        loss, q_written, got = sac_written.critic_loss_grads(params, hidden, obs, actions, target)
    assert torch.equal(q_written, q.detach()) and torch.equal(loss, loss_q.detach())
    for e, g in zip(expected, got, strict=True):
        assert e.shape == g.shape and torch.equal(e, g)
    # actor loss through the frozen critic (SACLearner._policy's expression with this noise)
    learner = SACLearner.__new__(SACLearner)
    learner.actor = actor
    learner._noise = lambda _: noise  # type: ignore[method-assign]
    action, log_prob = learner._policy(obs)
    frozen = [p.detach() for p in params]
    q_pi = critic(obs, action, frozen).min(0).values
    actor_params = list(actor.parameters())
    loss_pi = (alpha * log_prob - q_pi).mean()
    expected = _autograd_grads(loss_pi, actor_params)
    with torch.no_grad():
        loss_m, log_prob_m, got = sac_written.actor_loss_grads(actor, frozen, hidden, obs, noise,
                                                             alpha)
    assert torch.equal(loss_m, loss_pi.detach()) and torch.equal(log_prob_m, log_prob.detach())
    for e, g in zip(expected, got, strict=True):
        assert e.shape == g.shape and torch.equal(e, g)
    # temperature loss
    log_alpha = torch.tensor(-1.2, requires_grad=True)
    lp = log_prob.detach()
    (expected_alpha,) = _autograd_grads(-(log_alpha * (lp - 2.0)).mean(), [log_alpha])
    assert torch.equal(sac_written.alpha_loss_grad(lp, -2.0), expected_alpha)


def test_lean_adams_apply_gradients_is_its_step() -> None:
    torch.manual_seed(0)
    a, b = torch.nn.Linear(6, 4), torch.nn.Linear(6, 4)
    b.load_state_dict(a.state_dict())
    opt_a, opt_b = LeanAdam(a.parameters(), 1e-2), LeanAdam(b.parameters(), 1e-2)
    for _ in range(4):
        grads = [torch.randn_like(p) for p in a.parameters()]
        for p, g in zip(a.parameters(), grads, strict=True):
            p.grad = g.clone()
        opt_a.step()
        opt_b.apply_gradients(grads)
        assert all(torch.equal(x, y) for x, y in zip(a.parameters(), b.parameters(), strict=True))
    assert all(p.grad is None for p in b.parameters())
    with pytest.raises(ValueError, match="2 gradients expected"):
        opt_b.apply_gradients([torch.zeros(4, 6)])


def test_written_gradients_reject_what_they_do_not_write_out() -> None:
    settings = dataclasses.replace(SETTINGS[2], gradients="written")
    storage = _storage(32, 5, 2)
    with pytest.raises(ValueError, match="critic_layer_norm needs gradients='autograd'"):
        SACLearner(dataclasses.replace(settings, critic_layer_norm=True), storage)
    with pytest.raises(ValueError, match="covers ReLU actors"):
        SACLearner(settings, storage, actor=SquashedGaussianActor(5, 2, (8, 8), "tanh"))
    with pytest.raises(ValueError, match="gradients must be one of"):
        SACLearner(dataclasses.replace(settings, gradients="jit"), storage)


def test_sac_takes_the_kernel_from_config(tiny_train: Callable[..., DictConfig]) -> None:
    algo = build_algorithm(tiny_train("sac", "algo.gradients=written"))
    assert algo._core.settings.gradients == "written"
    assert build_algorithm(tiny_train("sac"))._core.settings.gradients == "autograd"
    with pytest.raises(InstantiationException, match="gradients must be one of"):
        build_algorithm(tiny_train("sac", "algo.gradients=fast"))


def test_resume_ignores_sacs_gradient_choice_only(tiny_train: Callable[..., DictConfig]) -> None:
    saved = tiny_train("sac")
    assert _config_differences(saved, tiny_train("sac", "algo.gradients=written")) == []
    assert _config_differences(saved, tiny_train("sac", "algo.tau=0.01")) == ["algo.tau"]
    # PPO's written derivatives differ from autograd's in the last bits: a difference there
    ppo = tiny_train("ppo_lag")
    assert _config_differences(ppo, tiny_train("ppo_lag", "algo.gradients=autograd")) == [
        "algo.gradients"]


@pytest.mark.parametrize("activation", ["relu", "tanh", "elu"])
def test_forward_mlp_is_the_modules_forward(activation: str) -> None:
    """The direct calls of forward_mlp (what the actor collects with) against the modules."""
    torch.manual_seed(2)
    net = mlp(6, (16, 8), 3, activation)
    x = torch.randn(10, 6) * 2.0
    assert torch.equal(forward_mlp(net, x), net(x))
