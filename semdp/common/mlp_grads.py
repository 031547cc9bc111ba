"""Hand-written derivatives of the MLPs of :func:`~semdp.common.networks.mlp` (``Linear, act,
..., Linear`` with tanh or ReLU), for the update steps whose autograd bookkeeping costs more
than their arithmetic (:mod:`semdp.common.stacked_critics`, :mod:`semdp.common.gaussian_fisher`).
"""

from __future__ import annotations

from collections.abc import Callable

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
