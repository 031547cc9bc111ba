"""The written kernels are checked at construction against the algorithms' own losses: an edit
to ``PPO.actor_loss``, ``critic_loss`` or SAC's losses that the kernel does not mirror fails the
presets' (written) configuration by the kernel's name, and changes an autograd run."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import pytest
import torch
from omegaconf import DictConfig
from torch.nn.utils import parameters_to_vector

from semdp.algos import critic_regression
from semdp.algos.kernels.written import KernelMismatch
from semdp.algos.ppo import PPO
from semdp.algos.sac.learner import LearnerSettings, SACLearner
from semdp.algos.trpo import TRPO
from semdp.cli.train import build_algorithm
from semdp.common.seeding import seed_everything

ORIGINAL_ACTOR_LOSS = PPO.actor_loss
ORIGINAL_CRITIC_LOSS = critic_regression.critic_loss


def _entropy_bonus(self: PPO, *args: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A planted edit: PPO's loss with an entropy bonus of 0.1 the kernel does not have."""
    loss, entropy = ORIGINAL_ACTOR_LOSS(self, *args)
    return loss - 0.1 * entropy, entropy


def _halved_cost_critic(*args: Any) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A planted edit: the critics' loss with the cost critic's error weighted by 1/2."""
    loss, loss_v, loss_vc = ORIGINAL_CRITIC_LOSS(*args)
    return loss - 0.5 * loss_vc, loss_v, loss_vc


def _one_update(cfg: DictConfig) -> torch.Tensor:
    """The actor and critics' parameters after one epoch's update of ``cfg``'s algorithm."""
    trainer = build_algorithm(cfg)
    stats = trainer.collect_rollout()
    trainer.before_update(stats)
    trainer._update(trainer.compute_batch())
    return torch.cat([parameters_to_vector(net.parameters()).detach()
                      for net in (trainer.actor, trainer.critic_r, trainer.critic_c)])


def test_the_presets_choose_the_written_kernel(tiny_train: Callable[..., DictConfig]) -> None:
    assert build_algorithm(tiny_train("ppo_lag")).kernel.name == "written"


@pytest.mark.parametrize(("target", "name", "edit", "kernel"), [
    (PPO, "actor_loss", _entropy_bonus, "PPOActorStep"),
    (critic_regression, "critic_loss", _halved_cost_critic, "StackedCritics"),
])
def test_an_unmirrored_edit_fails_the_default_config_and_changes_an_autograd_run(
    tiny_train: Callable[..., DictConfig], monkeypatch: pytest.MonkeyPatch,
    target: Any, name: str, edit: Callable[..., Any], kernel: str,
) -> None:
    before = _one_update(tiny_train("ppo_lag", "algo.gradients=autograd"))
    monkeypatch.setattr(target, name, edit)
    with pytest.raises(Exception, match=kernel) as failure:  # Hydra wraps the KernelMismatch
        build_algorithm(tiny_train("ppo_lag"))  # the preset: gradients=written
    assert KernelMismatch.__name__ in str(failure.value)
    assert "algo.gradients=autograd" in str(failure.value)
    seed_everything(0)  # as the fixture seeded the run before the edit
    after = _one_update(tiny_train("ppo_lag", "algo.gradients=autograd"))
    assert (after - before).abs().max() > 1e-6


def test_the_check_draws_nothing_from_the_runs_generators(
    tiny_train: Callable[..., DictConfig]
) -> None:
    states = []
    for gradients in ("autograd", "written"):
        seed_everything(0)
        build_algorithm(tiny_train("ppo_lag", f"algo.gradients={gradients}"))
        states.append(torch.get_rng_state())
    assert torch.equal(states[0], states[1])


# ----------------------------------------------------------------- SAC
SAC_SETTINGS = LearnerSettings(6, 2, (16, 16), 3e-4, 1e-3, 0.99, 0.005, 32, 1, 0.5, True, -2.0,
                               1e-3, 0)
ORIGINAL_SAC = {name: getattr(SACLearner, name)
                for name in ("critic_loss", "actor_loss", "alpha_loss")}


def _sac_edit(name: str) -> Callable[..., Any]:
    """A planted edit of one of SAC's losses (a term that moves the gradient's direction: Adam
    would hide a mere rescaling)."""
    def edited(self: SACLearner, *args: Any) -> Any:
        out = ORIGINAL_SAC[name](self, *args)
        if name == "alpha_loss":
            return out + 0.5 * self.log_alpha
        loss, other = out  # critic: (loss, Q); actor: (loss, log pi)
        return loss + 0.1 * other.square().mean(), other
    return edited


def _sac_run(settings: LearnerSettings) -> torch.Tensor:
    """The actor, critic and temperature after 4 updates of a learner on random replay rows."""
    g = torch.Generator().manual_seed(3)
    n = 64
    storage = {"obs": torch.randn(n, settings.obs_dim, generator=g),
               "next_obs": torch.randn(n, settings.obs_dim, generator=g),
               "actions": torch.rand(n, settings.act_dim, generator=g) * 2 - 1,
               "rewards": torch.randn(n, generator=g), "terminated": torch.zeros(n)}
    seed_everything(0)
    learner = SACLearner(settings, storage)
    learner.run(4, n)
    return torch.cat([parameters_to_vector(learner.actor.parameters()).detach(),
                      parameters_to_vector(learner.critic.parameters()).detach(),
                      learner.log_alpha.detach().reshape(1)])


@pytest.mark.parametrize("name", ["critic_loss", "actor_loss", "alpha_loss"])
def test_an_unmirrored_edit_of_sacs_loss_fails_the_written_kernel_and_changes_autograd(
    monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    written = dataclasses.replace(SAC_SETTINGS, gradients="written")
    before = _sac_run(SAC_SETTINGS)
    assert torch.equal(_sac_run(written), before)  # the kernel: autograd's floats
    monkeypatch.setattr(SACLearner, name, _sac_edit(name))
    with pytest.raises(KernelMismatch, match="sac_written") as failure:
        _sac_run(written)
    assert "algo.gradients=autograd" in str(failure.value)
    assert (_sac_run(SAC_SETTINGS) - before).abs().max() > 1e-7


def test_the_main_job_chooses_sacs_written_kernel(
    compose_train: Callable[..., DictConfig]
) -> None:
    cfg = compose_train("experiment=semdp", "budget=ci")
    assert cfg.algo.gradients == "written"


# ----------------------------------------------------------------- TRPO's Fisher-vector product
def test_an_unmirrored_edit_of_trpos_kl_fails_the_written_fisher_product(
    tiny_train: Callable[..., DictConfig], monkeypatch: pytest.MonkeyPatch
) -> None:
    assert build_algorithm(tiny_train("trpo_lag")).kernel.name == "written"  # the preset
    original = TRPO.mean_kl
    monkeypatch.setattr(TRPO, "mean_kl", lambda self, obs, old: 1.5 * original(self, obs, old))
    with pytest.raises(Exception, match="GaussianFisher") as failure:
        build_algorithm(tiny_train("trpo_lag"))
    assert "algo.gradients=autograd" in str(failure.value)
    build_algorithm(tiny_train("trpo_lag", "algo.gradients=autograd"))  # runs the edit
