"""The written-out Fisher-vector product of the Gaussian actor against autograd and by hand."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch
from omegaconf import DictConfig
from torch import nn
from torch.distributions import Normal, kl_divergence
from torch.nn.utils import parameters_to_vector

from semdp.algos.kernels.gaussian_fisher import GaussianFisher
from semdp.cli.train import build_algorithm
from semdp.common.networks import GaussianActor


def _autograd_fvp(actor: GaussianActor, obs: torch.Tensor, v: torch.Tensor,
                  damping: float) -> torch.Tensor:
    """Hessian of the mean KL(old || theta) at theta = old, times v (double backward)."""
    with torch.no_grad():
        d = actor.distribution(obs)
        old = Normal(d.mean.clone(), d.stddev.clone())
    params = list(actor.parameters())
    kl = kl_divergence(old, actor.distribution(obs)).sum(-1).mean()
    grads = torch.autograd.grad(kl, params, create_graph=True)
    flat = torch.cat([g.reshape(-1) for g in grads])
    hv = torch.autograd.grad(flat @ v, params)
    return torch.cat([h.reshape(-1) for h in hv]) + damping * v


@pytest.mark.parametrize(("hidden", "activation"),
                         [((16, 16), "tanh"), ((8,), "relu"), ((), "tanh")])
def test_analytic_product_equals_the_autograd_hessian_of_the_kl(
    hidden: tuple[int, ...], activation: str
) -> None:
    torch.manual_seed(1)
    actor = GaussianActor(5, 3, hidden, activation, log_std_init=-0.4)
    with torch.no_grad():
        actor.log_std.add_(torch.tensor([0.0, 0.3, -0.2]))
        for p in actor.mean_net.parameters():
            p.add_(0.2 * torch.randn_like(p))
    obs = torch.randn(64, 5)
    fisher = GaussianFisher.build(actor, obs, damping=0.1)
    assert fisher is not None
    for _ in range(3):
        v = torch.randn(sum(p.numel() for p in actor.parameters()))
        torch.testing.assert_close(fisher(v), _autograd_fvp(actor, obs, v, 0.1),
                                   rtol=1e-5, atol=1e-6)


def test_linear_mean_by_hand() -> None:
    """mu = w.x + b, one action: F_ww = mean(x x^T) / sigma^2, F_bb = 1 / sigma^2,
    F_log_std = 2, no mean-log_std cross terms."""
    actor = GaussianActor(2, 1, (), "tanh", log_std_init=0.5)
    obs = torch.tensor([[1.0, 2.0], [3.0, -1.0]])
    fisher = GaussianFisher.build(actor, obs, damping=0.0)
    assert fisher is not None
    inv_var = float(torch.exp(torch.tensor(-1.0)))
    # layout: log_std, w (1x2), b
    v = torch.tensor([0.7, 1.0, -2.0, 0.5])
    xx = (torch.outer(obs[0], obs[0]) + torch.outer(obs[1], obs[1])) / 2  # [[5, -0.5], [-0.5, 2.5]]
    x_mean = obs.mean(0)  # F_wb = mean(x) / sigma^2
    expected_w = inv_var * (xx @ v[1:3] + x_mean * v[3])
    expected_b = inv_var * (x_mean @ v[1:3] + v[3])
    expected = torch.cat([torch.tensor([2 * 0.7]), expected_w, expected_b.reshape(1)])
    torch.testing.assert_close(fisher(v), expected)


def test_other_actors_are_not_covered() -> None:
    class NoStd(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.mean_net = nn.Sequential(nn.Linear(3, 2))

    assert GaussianFisher.build(NoStd(), torch.zeros(4, 3), 0.1) is None
    elu = GaussianActor(3, 2, (4,), "elu")
    assert GaussianFisher.build(elu, torch.zeros(4, 3), 0.1) is None


@pytest.mark.parametrize("algo", ["trpo_lag", "cpo"])
def test_trpo_and_cpo_steps_agree_with_the_autograd_product(
    algo: str, tiny_train: Callable[..., DictConfig]
) -> None:
    """One actor update on the same batch: the same accepted step, parameters equal to
    rounding (the line search and CPO's case selection see the same numbers)."""
    results = []
    for product in ("written", "autograd"):
        torch.manual_seed(0)
        trainer = build_algorithm(tiny_train(algo, f"algo.gradients={product}",
                                             "algo.vectorization=sync"))
        stats = trainer.collect_rollout()
        trainer.before_update(stats)
        before = parameters_to_vector(trainer.actor.parameters()).detach().clone()
        out = trainer.update_actor(trainer.compute_batch())
        after = parameters_to_vector(trainer.actor.parameters()).detach()
        assert (after - before).abs().max() > 1e-4  # a step was taken
        results.append((out, after))
        trainer.close_helpers()
    (out_a, theta_a), (out_b, theta_b) = results
    assert out_a["step_frac"] == out_b["step_frac"] > 0
    torch.testing.assert_close(theta_a, theta_b, rtol=1e-4, atol=1e-6)


def test_unknown_product_is_rejected(tiny_train: Callable[..., DictConfig]) -> None:
    with pytest.raises(Exception, match="gradients must be one of"):
        build_algorithm(tiny_train("trpo_lag", "algo.gradients=exact"))
