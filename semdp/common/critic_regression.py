"""Regression of the reward and cost critics on their GAE returns (semdp/README.md, PPO/TRPO).

Minibatch passes over the batch, one permutation per pass; per minibatch the squared errors of
V_r and V_c plus ``l2`` times the summed squared weights, the gradient norm of both critics
clipped together, one optimiser step. The same function runs in the trainer and in the critic
helper process (:mod:`semdp.common.critic_worker`), so both give bit-identical critics. The
default MLP critics with :class:`~semdp.common.optim.FlatAdam` take the stacked path with
hand-written gradients (:mod:`semdp.common.stacked_critics`, ~3x faster); ``autograd=True``
(or any other architecture/optimiser) takes the autograd path below.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import torch
from torch import nn

from semdp.common.optim import clip_grad_norm
from semdp.common.stacked_critics import StackedCritics


class CriticTargets(NamedTuple):
    """What the critics regress on: normalised observations and both GAE returns."""

    obs: torch.Tensor
    ret_r: torch.Tensor
    ret_c: torch.Tensor


def l2_weights(*critics: nn.Module) -> list[torch.Tensor]:
    """The weight matrices (not the biases) whose squares the L2 term sums, in order."""
    return [p for net in critics for name, p in net.named_parameters() if name.endswith("weight")]


def regress_critics(
    critic_r: nn.Module,
    critic_c: nn.Module,
    optimizer: torch.optim.Optimizer,
    targets: CriticTargets,
    perms: Sequence[torch.Tensor],
    minibatch: int,
    l2: float,
    max_grad_norm: float | None,
    stop: Callable[[], bool] | None = None,
    autograd: bool = False,
) -> tuple[float, float] | None:
    """Passes over ``targets`` in the orders ``perms``; return the last minibatch's losses.

    Args:
        critic_r, critic_c: the critics (trained in place).
        optimizer: the optimiser of both critics' parameters.
        targets: observations and returns.
        perms: one permutation of the batch indices per pass.
        minibatch: minibatch size.
        l2: coefficient of the summed squared weights.
        max_grad_norm: joint gradient-norm clip (``None`` = off).
        stop: polled before each minibatch; ``True`` abandons the regression.
        autograd: use the autograd path even where the stacked one applies.

    Returns:
        ``(loss_v, loss_vc)`` of the last minibatch (0.0 without any), or ``None`` if stopped.
    """
    stacked = None if autograd else StackedCritics.build(critic_r, critic_c, optimizer)
    if stacked is not None:  # the same regression with hand-written gradients
        return stacked.regress(*targets, perms, minibatch, l2, max_grad_norm, stop)
    weights = l2_weights(critic_r, critic_c)
    params = [*critic_r.parameters(), *critic_c.parameters()]
    n = targets.obs.shape[0]
    loss_v = loss_vc = torch.tensor(0.0)
    for perm in perms:
        # one gather per pass; the minibatches are slices of it
        all_obs, all_ret_r, all_ret_c = (x[perm] for x in targets)
        for start in range(0, n, minibatch):
            if stop is not None and stop():
                return None
            idx = slice(start, start + minibatch)
            obs = all_obs[idx]
            loss_v = ((critic_r(obs) - all_ret_r[idx]) ** 2).mean()
            loss_vc = ((critic_c(obs) - all_ret_c[idx]) ** 2).mean()
            weight_norm = sum((p**2).sum() for p in weights)
            optimizer.zero_grad()
            (loss_v + loss_vc + l2 * weight_norm).backward()
            if max_grad_norm is not None:
                clip_grad_norm(params, max_grad_norm)
            optimizer.step()
    return loss_v.item(), loss_vc.item()
