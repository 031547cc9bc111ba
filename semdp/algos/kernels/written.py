"""The written-out update kernel (``gradients="written"``): hand-derived gradients of the
default MLP actor and critics in place of autograd (semdp/algos/kernels/__init__.py).

Each method returns the fast implementation where the networks and optimiser allow it
(``FlatAdam``, the default MLPs), else ``None``: the caller then takes its own autograd path,
exactly as :class:`~semdp.algos.on_policy.Autograd` makes it do everywhere.

The losses are defined once, in autograd, by the algorithms (:meth:`semdp.algos.ppo.PPO.actor_loss`,
:func:`semdp.algos.critic_regression.critic_loss`); a kernel here restates their derivatives by
hand, so the ``check_*`` methods, called when an algorithm is built, compare each kernel with the
algorithm's own loss on a random minibatch drawn from a generator of their own (the run's random
streams are not touched): loss value and gradient to :data:`RTOL` of their size. An edit to a
loss that the kernel does not mirror fails there, naming the kernel and ``algo.gradients=autograd``.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn
from torch.distributions import Normal

from semdp.algos.kernels.gaussian_fisher import GaussianFisher
from semdp.algos.kernels.mlp_grads import KernelMismatch
from semdp.algos.kernels.ppo_actor_step import PPOActorStep
from semdp.algos.kernels.stacked_critics import StackedCritics

#: Tolerance of the construction check, relative to the largest entry of the autograd value
#: (the kernels agree with autograd to float32 rounding, ~1e-7; an unmirrored edit moves them by
#: far more).
RTOL = 1e-4
#: Size of the check's random minibatch, and its generator's seed.
CHECK_BATCH, CHECK_SEED = 64, 0

__all__ = ["CHECK_BATCH", "CHECK_SEED", "RTOL", "KernelMismatch", "WrittenDerivatives"]


def _compare(kernel: str, module: str, definition: str, what: str, expected: torch.Tensor,
             actual: torch.Tensor) -> None:
    """Raise :class:`KernelMismatch` unless ``actual`` is ``expected`` to :data:`RTOL`."""
    expected, actual = expected.detach().reshape(-1), actual.detach().reshape(-1)
    scale = max(float(expected.abs().max()), 1e-6)
    error = float((expected - actual).abs().max())
    if not error <= RTOL * scale:
        raise KernelMismatch(
            f"the written kernel {kernel} ({module}) disagrees with {definition} on a random "
            f"minibatch: {what} differs by {error:.3g} (tolerance {RTOL:g} x {scale:.3g}). The "
            f"kernel restates that loss's derivatives by hand: mirror the edit in {module}, or "
            f"turn the kernel off with the config option algo.gradients=autograd "
            f"(gradients='autograd').")


def _flat_grad(loss: torch.Tensor, params: list[torch.Tensor]) -> torch.Tensor:
    """d loss / d params concatenated in parameter order (no ``.grad`` is written)."""
    return torch.cat([g.reshape(-1) for g in torch.autograd.grad(loss, params)])


class WrittenDerivatives:
    """The kernel of written-out derivatives (see the module docstring)."""

    name = "written"

    def check_critics(
        self, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer,
        l2: float, loss: Callable[..., tuple[torch.Tensor, ...]], obs_dim: int,
    ) -> None:
        """:class:`StackedCritics` against ``loss`` (the algorithm's
        :func:`~semdp.algos.critic_regression.critic_loss`) on a random minibatch."""
        stacked = self.critics(critic_r, critic_c, optimizer)
        if stacked is None:
            return
        gen = torch.Generator().manual_seed(CHECK_SEED)
        dtype = next(critic_r.parameters()).dtype
        obs, ret_r, ret_c = (torch.randn(*shape, generator=gen, dtype=dtype)
                             for shape in ((CHECK_BATCH, obs_dim), (CHECK_BATCH,), (CHECK_BATCH,)))
        expected = loss(critic_r, critic_c, obs, ret_r, ret_c, l2)[0]
        grad = _flat_grad(expected, [*critic_r.parameters(), *critic_c.parameters()])
        value, written = stacked.loss_and_grad(obs, ret_r, ret_c, l2)
        where = ("StackedCritics", "semdp/algos/kernels/stacked_critics.py",
                 "semdp.algos.critic_regression.critic_loss")
        _compare(*where, "the loss", expected, value)
        _compare(*where, "the gradient", grad, written)

    def check_fisher(
        self, actor: nn.Module,
        product: Callable[[torch.Tensor, Normal], Callable[[torch.Tensor], torch.Tensor]],
        damping: float, obs_dim: int,
    ) -> None:
        """:class:`GaussianFisher` against ``product`` (TRPO's ``kl_hessian_product``, the
        double-backward Hessian of its mean KL) at random observations and vector."""
        gen = torch.Generator().manual_seed(CHECK_SEED)
        dtype = actor.log_std.dtype
        obs = torch.randn(CHECK_BATCH, obs_dim, generator=gen, dtype=dtype)
        fisher = self.fisher(actor, obs, damping)
        if fisher is None:
            return
        v = torch.randn(sum(p.numel() for p in actor.parameters()), generator=gen, dtype=dtype)
        with torch.no_grad():
            dist = actor.distribution(obs)
            old = Normal(dist.mean.detach(), dist.stddev.detach())
        _compare("GaussianFisher", "semdp/algos/kernels/gaussian_fisher.py",
                 "semdp.algos.trpo.TRPO.kl_hessian_product", "the Fisher-vector product",
                 product(obs, old)(v), fisher(v))

    def check_ppo(
        self, actor: nn.Module, optimizer: torch.optim.Optimizer,
        loss: Callable[..., tuple[torch.Tensor, torch.Tensor]], clip_range: float,
        ent_coef: float, obs_dim: int, act_dim: int,
    ) -> None:
        """:class:`PPOActorStep` against ``loss`` (``PPO.actor_loss``) on a random minibatch whose
        ratios fall both inside and outside the clip range."""
        step = self.ppo_step(actor, optimizer)
        if step is None:
            return
        gen = torch.Generator().manual_seed(CHECK_SEED)
        dtype = actor.log_std.dtype
        obs = torch.randn(CHECK_BATCH, obs_dim, generator=gen, dtype=dtype)
        actions = torch.randn(CHECK_BATCH, act_dim, generator=gen, dtype=dtype)
        adv = torch.randn(CHECK_BATCH, generator=gen, dtype=dtype)
        with torch.no_grad():
            old = actor.log_prob(obs, actions) + 0.3 * torch.randn(CHECK_BATCH, generator=gen,
                                                                   dtype=dtype)
        expected, entropy = loss(obs, actions, old, adv)
        grad = _flat_grad(expected, list(actor.parameters()))
        value, written_entropy = step.loss_and_grad(obs, actions, old, adv, clip_range, ent_coef)
        where = ("PPOActorStep", "semdp/algos/kernels/ppo_actor_step.py",
                 "semdp.algos.ppo.PPO.actor_loss")
        _compare(*where, "the loss", expected, value)
        _compare(*where, "the entropy", entropy, written_entropy)
        _compare(*where, "the gradient", grad, step.grad)

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
