"""The stacked critic regression (hand-written gradients) against the autograd regression."""

from __future__ import annotations

import copy

import pytest
import torch

from semdp.algos.critic_regression import CriticTargets, regress_critics
from semdp.algos.kernels.stacked_critics import StackedCritics
from semdp.algos.kernels.written import WrittenDerivatives
from semdp.algos.on_policy import Autograd
from semdp.common.networks import ValueCritic
from semdp.common.optim import FlatAdam


def _setup(
    hidden: tuple[int, ...], activation: str, seed: int = 0
) -> tuple[ValueCritic, ValueCritic, CriticTargets]:
    torch.manual_seed(seed)
    obs_dim, n = 7, 96
    critic_r = ValueCritic(obs_dim, hidden, activation)
    critic_c = ValueCritic(obs_dim, hidden, activation)
    targets = CriticTargets(torch.randn(n, obs_dim), 3 * torch.randn(n), torch.rand(n))
    return critic_r, critic_c, targets


def _copies(
    critic_r: ValueCritic, critic_c: ValueCritic
) -> tuple[ValueCritic, ValueCritic, FlatAdam]:
    r, c = copy.deepcopy(critic_r), copy.deepcopy(critic_c)
    return r, c, FlatAdam([*r.parameters(), *c.parameters()], lr=1e-2)


@pytest.mark.parametrize(("hidden", "activation"),
                         [((16, 16), "tanh"), ((16,), "relu"), ((16, 8, 12), "tanh")])
@pytest.mark.parametrize("max_grad_norm", [0.05, None])
def test_stacked_regression_matches_autograd(
    hidden: tuple[int, ...], activation: str, max_grad_norm: float | None
) -> None:
    critic_r, critic_c, targets = _setup(hidden, activation)
    perms = [torch.randperm(96) for _ in range(3)]
    results = []
    for autograd in (True, False):
        r, c, opt = _copies(critic_r, critic_c)
        losses = regress_critics(r, c, opt, targets, perms, 20, 1e-2, max_grad_norm,
                                 kernel=Autograd() if autograd else WrittenDerivatives())
        results.append((losses, [*r.parameters(), *c.parameters()], opt.state_dict()))
    (loss_a, params_a, state_a), (loss_s, params_s, state_s) = results
    assert loss_s == pytest.approx(loss_a, rel=1e-5)
    # the critics moved (15 Adam steps at lr 1e-2), and both paths moved them the same way
    assert any((p - q).abs().max() > 1e-2 for p, q in
               zip(params_a, [*critic_r.parameters(), *critic_c.parameters()], strict=True))
    for p, q in zip(params_a, params_s, strict=True):
        torch.testing.assert_close(q, p, rtol=1e-5, atol=1e-6)
    assert state_s["state"].keys() == state_a["state"].keys()
    for i, s in state_a["state"].items():
        assert float(state_s["state"][i]["step"]) == float(s["step"]) == 15.0
        torch.testing.assert_close(state_s["state"][i]["exp_avg"], s["exp_avg"],
                                   rtol=1e-4, atol=1e-7)


def test_one_step_equals_a_hand_computed_adam_step_on_the_autograd_gradient() -> None:
    """First Adam step moves every parameter by lr * sign(gradient) (m / sqrt(v) = g / |g|):
    the stacked gradient has autograd's signs, including the L2 term's."""
    critic_r, critic_c, targets = _setup((16, 16), "tanh", seed=3)
    r, c, _ = _copies(critic_r, critic_c)
    loss = ((r(targets.obs) - targets.ret_r) ** 2).mean() \
        + ((c(targets.obs) - targets.ret_c) ** 2).mean() \
        + 0.1 * sum((p ** 2).sum() for n, p in [*r.named_parameters(), *c.named_parameters()]
                    if n.endswith("weight"))
    params = [*r.parameters(), *c.parameters()]
    grads = torch.autograd.grad(loss, params)
    r2, c2, opt = _copies(critic_r, critic_c)
    regress_critics(r2, c2, opt, targets, [torch.arange(96)], 96, 0.1, None,
                    kernel=WrittenDerivatives())
    for p, p_new, g in zip(params, [*r2.parameters(), *c2.parameters()], grads, strict=True):
        expected = p.detach() - 1e-2 * torch.sign(g)
        torch.testing.assert_close(p_new, expected, rtol=0, atol=1e-6)


def test_other_architectures_and_optimisers_take_the_autograd_path() -> None:
    critic_r, critic_c, _ = _setup((16, 16), "tanh")
    other = ValueCritic(7, (16, 8), "tanh")
    elu_r, elu_c = ValueCritic(7, (16,), "elu"), ValueCritic(7, (16,), "elu")
    adam = torch.optim.Adam([*critic_r.parameters(), *critic_c.parameters()])
    assert StackedCritics.build(critic_r, critic_c, adam) is None
    assert StackedCritics.build(critic_r, other,
                                FlatAdam([*critic_r.parameters(), *other.parameters()])) is None
    assert StackedCritics.build(elu_r, elu_c,
                                FlatAdam([*elu_r.parameters(), *elu_c.parameters()])) is None
    swapped = FlatAdam([*critic_c.parameters(), *critic_r.parameters()])
    assert StackedCritics.build(critic_r, critic_c, swapped) is None
    ok = FlatAdam([*critic_r.parameters(), *critic_c.parameters()])
    assert StackedCritics.build(critic_r, critic_c, ok) is not None


def test_a_stopped_regression_returns_none_and_keeps_the_steps_made() -> None:
    critic_r, critic_c, targets = _setup((16, 16), "tanh")
    r, c, opt = _copies(critic_r, critic_c)
    calls = iter(range(100))
    out = regress_critics(r, c, opt, targets, [torch.arange(96)], 32, 0.0, None,
                          stop=lambda: next(calls) == 2, kernel=WrittenDerivatives())
    assert out is None
    assert float(opt.state_dict()["state"][0]["step"]) == 2.0
