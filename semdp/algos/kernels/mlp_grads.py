"""Hand-written derivatives of the MLPs of :func:`~semdp.common.networks.mlp` (``Linear, act,
..., Linear`` with tanh or ReLU), for the update steps whose autograd bookkeeping costs more
than their arithmetic (:mod:`semdp.algos.kernels.stacked_critics`,
:mod:`semdp.algos.kernels.gaussian_fisher`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import nn

#: Hidden activations with a hand-written derivative, as a function of the activation's output.
ACTIVATION_GRADS: dict[type[nn.Module], Callable[[torch.Tensor], torch.Tensor]] = {
    nn.Tanh: lambda h: 1 - h * h,
    nn.ReLU: lambda h: (h > 0).to(h.dtype),
}
#: The activations themselves.
ACTIVATIONS: dict[type[nn.Module], Callable[[torch.Tensor], torch.Tensor]] = {
    nn.Tanh: torch.tanh,
    nn.ReLU: torch.relu,
}


def mlp_layers(net: object) -> tuple[list[nn.Linear], list[type[nn.Module]]] | None:
    """The Linear layers and hidden activation types of ``net`` if it is a ``Linear, act, ...,
    Linear`` ``nn.Sequential`` with activations of :data:`ACTIVATION_GRADS` (else ``None``)."""
    if not isinstance(net, nn.Sequential) or len(net) % 2 == 0:
        return None
    linears, acts = list(net)[0::2], list(net)[1::2]
    if not all(type(m) is nn.Linear for m in linears):
        return None
    if not all(type(m) in ACTIVATION_GRADS for m in acts):
        return None
    return linears, [type(m) for m in acts]


def gaussian_actor_layers(
    actor: nn.Module,
) -> tuple[list[nn.Linear], list[type[nn.Module]]] | None:
    """The mean network's layers of a Gaussian actor whose parameters are a ``log_std`` vector,
    then a ``mean_net`` MLP of :func:`mlp_layers` (``None`` for any other actor)."""
    parts = mlp_layers(getattr(actor, "mean_net", None))
    log_std = getattr(actor, "log_std", None)
    if parts is None or not isinstance(log_std, torch.Tensor) or log_std.dim() != 1:
        return None
    expected = [log_std] + [p for m in parts[0] for p in (m.weight, m.bias)]
    params = list(actor.parameters())
    if len(params) != len(expected) or any(a is not b for a, b in
                                            zip(params, expected, strict=False)):
        return None
    return parts


def backprop_mlp(
    delta: torch.Tensor,
    inputs: Sequence[torch.Tensor],
    weights: Sequence[torch.Tensor],
    slopes: Sequence[torch.Tensor],
    grads: Sequence[tuple[torch.Tensor, torch.Tensor]],
) -> None:
    """Write ``d/dW`` and ``d/db`` of every layer into ``grads`` given ``delta`` = d/d(output).

    Shapes carry an optional leading batch of networks (the stacked critics): ``inputs[k]``
    ``(..., B, in_k)`` is layer ``k``'s input, ``weights[k]`` ``(..., out_k, in_k)``,
    ``slopes[k]`` the activation's derivative at hidden layer ``k`` (shape of ``inputs[k + 1]``),
    ``grads[k]`` the ``(..., out_k, in_k)`` and ``(..., out_k)`` tensors to fill.
    """
    for k in range(len(weights) - 1, -1, -1):
        gw, gb = grads[k]
        torch.matmul(delta.transpose(-1, -2), inputs[k], out=gw)
        torch.sum(delta, -2, out=gb)
        if k:
            delta = torch.matmul(delta, weights[k]) * slopes[k - 1]


class KernelMismatch(RuntimeError):
    """A written kernel disagrees with the loss it restates (checked when the algorithm is built:
    :class:`~semdp.algos.kernels.written.WrittenDerivatives`' ``check_*`` methods,
    :meth:`semdp.algos.sac.learner.SACLearner.check_written`)."""
