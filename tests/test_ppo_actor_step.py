"""PPO's written-out clipped-surrogate step against the autograd step of PPO's own loss
(:meth:`semdp.algos.ppo.PPO.actor_loss`)."""

from __future__ import annotations

import copy
from collections.abc import Callable

import pytest
import torch
from omegaconf import DictConfig
from torch.nn.utils import parameters_to_vector

from semdp.algos.kernels.ppo_actor_step import PPOActorStep
from semdp.algos.ppo import PPO
from semdp.cli.train import build_algorithm
from semdp.common.networks import GaussianActor
from semdp.common.optim import FlatAdam, clip_grad_norm
from semdp.envs import make_vec_env


def _autograd_step(ppo: PPO, obs: torch.Tensor, actions: torch.Tensor, old: torch.Tensor,
                   adv: torch.Tensor) -> float:
    """One minibatch step of ``ppo``'s actor on its own loss, through autograd."""
    loss, _ = ppo.actor_loss(obs, actions, old, adv)
    ppo.actor_optimizer.zero_grad()
    loss.backward()
    if ppo.max_grad_norm is not None:
        clip_grad_norm(list(ppo.actor.parameters()), ppo.max_grad_norm)
    ppo.actor_optimizer.step()
    return float(loss.detach())


@pytest.mark.parametrize(("hidden", "activation", "ent", "max_norm"),
                         [((16, 16), "tanh", 0.0, 0.5), ((8,), "relu", 0.01, None)])
def test_written_step_equals_the_autograd_step_of_ppos_loss(
    hidden: tuple[int, ...], activation: str, ent: float, max_norm: float | None
) -> None:
    envs = make_vec_env({"id": "sims/SafetyPointGoal1-v0", "num_envs": 1}, seed=0)
    ppo = PPO(envs, None, seed=0, steps_per_epoch=64, actor_lr=3e-3, clip_range=0.2,
              ent_coef=ent, max_grad_norm=max_norm, hidden_sizes=hidden, activation=activation,
              log_std_init=-0.3)
    actor = ppo.actor
    torch.manual_seed(0)
    obs, actions = torch.randn(64, ppo.obs_dim), torch.randn(64, ppo.act_dim)
    adv = torch.randn(64)
    with torch.no_grad():  # an "old" policy such that some ratios leave the clip range
        old = actor.log_prob(obs, actions) + 0.3 * torch.randn(64)
    start = parameters_to_vector(actor.parameters()).detach().clone()
    clone = copy.deepcopy(actor)
    written = PPOActorStep.build(clone, FlatAdam(clone.parameters(), lr=3e-3))
    assert written is not None
    ratio = (actor.log_prob(obs, actions) - old).exp()
    assert ((ratio < 0.8) | (ratio > 1.2)).any() and ((ratio > 0.8) & (ratio < 1.2)).any()
    for _ in range(8):
        loss_a = _autograd_step(ppo, obs, actions, old, adv)
        loss_w, _ = written.step(obs, actions, old, adv, ppo.clip_range, ppo.ent_coef,
                                 ppo.max_grad_norm)
        assert float(loss_w) == pytest.approx(loss_a, rel=1e-5, abs=1e-7)
    theta_a = parameters_to_vector(actor.parameters()).detach()
    theta_w = parameters_to_vector(clone.parameters()).detach()
    assert (theta_a - start).abs().max() > 1e-3
    torch.testing.assert_close(theta_w, theta_a, rtol=1e-5, atol=1e-6)
    envs.close()


def test_other_optimisers_take_the_autograd_step() -> None:
    actor = GaussianActor(4, 2)
    assert PPOActorStep.build(actor, torch.optim.Adam(actor.parameters())) is None
    assert PPOActorStep.build(GaussianActor(4, 2, (8,), "elu"),
                              FlatAdam(GaussianActor(4, 2).parameters())) is None


def test_ppo_update_written_or_autograd_gives_the_same_actor(
    tiny_train: Callable[..., DictConfig]
) -> None:
    thetas = []
    for gradients in ("written", "autograd"):
        torch.manual_seed(0)
        trainer = build_algorithm(tiny_train("ppo_lag", f"algo.gradients={gradients}",
                                             "algo.vectorization=sync",
                                             "algo.parallel_critics=false"))
        stats = trainer.collect_rollout()
        trainer.before_update(stats)
        out = trainer._update(trainer.compute_batch())
        assert out["update_passes"] == 2
        thetas.append(parameters_to_vector(trainer.actor.parameters()).detach())
    torch.testing.assert_close(thetas[0], thetas[1], rtol=1e-5, atol=1e-6)
