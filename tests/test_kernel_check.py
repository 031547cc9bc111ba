"""The written kernels are checked at construction against the algorithms' own losses: an edit
to ``PPO.actor_loss`` or ``critic_loss`` that the kernel does not mirror fails the presets'
(written) configuration by the kernel's name, and changes an autograd run."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
import torch
from omegaconf import DictConfig
from torch.nn.utils import parameters_to_vector

from semdp.algos import on_policy
from semdp.algos.fast.written import KernelMismatch
from semdp.algos.ppo import PPO
from semdp.cli.train import build_algorithm
from semdp.common.seeding import seed_everything

ORIGINAL_ACTOR_LOSS = PPO.actor_loss
ORIGINAL_CRITIC_LOSS = on_policy.critic_loss


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
    (on_policy, "critic_loss", _halved_cost_critic, "StackedCritics"),
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
