"""The critics' regression of the on-policy algorithms (thesis Eqs. 2.4-2.7; step 5 of an epoch
of :class:`~semdp.algos.on_policy.OnPolicyAlgorithm`): minibatch passes of the reward critic V_r
and the cost critic V_c on their GAE returns, each step's loss defined once, in autograd, by
:func:`critic_loss`.

The written kernel's stacked regression (:mod:`semdp.algos.kernels.stacked_critics`,
``gradients=written``) is checked against :func:`critic_loss` when an algorithm is built, and the
critic helper process (:mod:`semdp.algos.helpers.critic_helper`) runs :func:`regress_critics`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import torch
from torch import nn

from semdp.common.optim import clip_grad_norm


class CriticTargets(NamedTuple):
    """What the critics regress on: normalised observations and both GAE returns."""

    obs: torch.Tensor
    ret_r: torch.Tensor
    ret_c: torch.Tensor


def critic_loss(
    critic_r: nn.Module, critic_c: nn.Module, obs: torch.Tensor, ret_r: torch.Tensor,
    ret_c: torch.Tensor, l2: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(loss, loss_v, loss_vc)`` of a critics' minibatch: the squared errors of V_r and V_c on
    their GAE returns plus ``l2`` times both critics' summed
    squared weights (OmniSafe's ``critic_norm_coef``). The written kernel's stacked regression
    (``gradients=written``) is checked against this at construction."""
    loss_v = ((critic_r(obs) - ret_r) ** 2).mean()
    loss_vc = ((critic_c(obs) - ret_c) ** 2).mean()
    weight_norm = sum((p**2).sum() for net in (critic_r, critic_c)
                      for name, p in net.named_parameters() if name.endswith("weight"))
    return loss_v + loss_vc + l2 * weight_norm, loss_v, loss_vc


def regress_critics(
    critic_r: nn.Module,
    critic_c: nn.Module,
    optimizer: torch.optim.Optimizer,
    targets: Sequence[torch.Tensor],
    perms: Sequence[torch.Tensor],
    minibatch: int,
    l2: float,
    max_grad_norm: float | None,
    stop: Callable[[], bool] | None = None,
    kernel: Any = None,
) -> tuple[float, float] | None:
    """Minibatch passes of V_r and V_c on their returns; the last minibatch's losses.

    Per minibatch the squared errors of both critics plus ``l2`` times their summed squared
    weights (OmniSafe's ``critic_norm_coef``), the gradient norm of both clipped together, one
    optimiser step; one permutation per pass (``perms``).

    Args:
        critic_r, critic_c, optimizer: the critics (trained in place) and their optimiser.
        targets: :class:`CriticTargets` (or the tuple ``(obs, ret_r, ret_c)``).
        perms: one permutation of the batch indices per pass.
        minibatch: minibatch size.
        l2: coefficient of the summed squared weights.
        max_grad_norm: joint gradient-norm clip (``None`` = off).
        stop: polled before each minibatch; ``True`` abandons the regression (returns None).
        kernel: the update kernel (``None``: :class:`~semdp.algos.on_policy.Autograd`; the
            written one regresses both as one stacked network).
    """
    stacked = None if kernel is None else kernel.critics(critic_r, critic_c, optimizer)
    if stacked is not None:
        return stacked.regress(*targets, perms, minibatch, l2, max_grad_norm, stop)
    params = [*critic_r.parameters(), *critic_c.parameters()]
    n = targets[0].shape[0]
    loss_v = loss_vc = torch.tensor(0.0)
    for perm in perms:
        all_obs, all_ret_r, all_ret_c = (x[perm] for x in targets)  # one gather per pass
        for start in range(0, n, minibatch):
            if stop is not None and stop():
                return None
            idx = slice(start, start + minibatch)
            loss, loss_v, loss_vc = critic_loss(critic_r, critic_c, all_obs[idx],
                                                all_ret_r[idx], all_ret_c[idx], l2)
            optimizer.zero_grad()
            loss.backward()
            if max_grad_norm is not None:
                clip_grad_norm(params, max_grad_norm)
            optimizer.step()
    return loss_v.item(), loss_vc.item()
