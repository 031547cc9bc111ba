"""The written-out update kernel (``gradients="written"``): hand-derived gradients of the
default MLP actor and critics in place of autograd (semdp/algos/fast/__init__.py).

Each method returns the fast implementation where the networks and optimiser allow it
(``FlatAdam``, the default MLPs), else ``None``: the caller then takes its own autograd path,
exactly as :class:`~semdp.algos.on_policy.Autograd` makes it do everywhere.
"""

from __future__ import annotations

import torch
from torch import nn

from semdp.algos.fast.gaussian_fisher import GaussianFisher
from semdp.algos.fast.ppo_actor_step import PPOActorStep
from semdp.algos.fast.stacked_critics import StackedCritics


class WrittenDerivatives:
    """The kernel of written-out derivatives (see the module docstring)."""

    name = "written"

    def critics(
        self, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer
    ) -> StackedCritics | None:
        """Both critics' regression as one stacked network (``regress(...)``)."""
        return StackedCritics.build(critic_r, critic_c, optimizer)

    def ppo_step(self, actor: nn.Module, optimizer: torch.optim.Optimizer) -> PPOActorStep | None:
        """PPO's clipped-surrogate minibatch step (``step(...)``)."""
        return PPOActorStep.build(actor, optimizer)

    def fisher(self, actor: nn.Module, obs: torch.Tensor, damping: float) -> GaussianFisher | None:
        """``v -> (F + damping I) v`` of the Gaussian actor at ``obs`` (TRPO, CPO)."""
        return GaussianFisher.build(actor, obs, damping)
