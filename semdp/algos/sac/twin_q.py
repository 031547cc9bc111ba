"""Twin Q networks evaluated as one batched network (SAC's clipped double Q, Haarnoja et al.
2018; the high level of the Safety-Embedded MDP, thesis §3.5, Alg. 2).

Two independent ReLU MLPs on ``[obs, act]`` (:func:`semdp.common.networks.mlp`, orthogonal
init), evaluated with half the operator calls: the first layers of both networks are one matrix
product on the shared input, the later layers one batched product each.

``layer_norm=True`` normalises every hidden layer before its ReLU (LayerNorm with a learnt
scale and shift per network), the critic of DroQ (Hiraoka et al. 2022) and RLPD (Ball et al.
2023) without dropout: the field's usual step towards sample-efficient SAC.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from semdp.common.networks import mlp


class FusedTwinQ(nn.Module):
    """Q1 and Q2 in one module; ``forward`` returns a ``(2, batch)`` tensor.

    Initialised as two :func:`~semdp.common.networks.mlp` ReLU networks, Q1's then Q2's (the
    draws of two separate networks), whose weights it then holds fused.

    Args:
        obs_dim, act_dim: input sizes.
        hidden_sizes: hidden layer widths (ReLU), the same for both networks.
        layer_norm: LayerNorm before every hidden ReLU (scale 1 and shift 0 at the start).
    """

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden_sizes: Sequence[int] = (256, 256),
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        hidden = [int(h) for h in hidden_sizes]
        if not hidden:
            raise ValueError("FusedTwinQ needs at least one hidden layer")
        nets = [[m for m in mlp(obs_dim + act_dim, hidden, 1, "relu") if isinstance(m, nn.Linear)]
                for _ in range(2)]
        first = [net[0] for net in nets]
        self.hidden = hidden
        self.w_in = nn.Parameter(torch.cat([f.weight.detach().T for f in first], dim=1))
        self.b_in = nn.Parameter(torch.cat([f.bias.detach() for f in first]))
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for layer in range(1, len(hidden) + 1):
            self.weights.append(nn.Parameter(
                torch.stack([net[layer].weight.detach().T for net in nets]).contiguous()))
            self.biases.append(nn.Parameter(
                torch.stack([net[layer].bias.detach()[None] for net in nets]).contiguous()))
        self.layer_norm = bool(layer_norm)
        if self.layer_norm:
            self.ln_scales = nn.ParameterList(
                [nn.Parameter(torch.ones(2, 1, h)) for h in hidden])
            self.ln_shifts = nn.ParameterList(
                [nn.Parameter(torch.zeros(2, 1, h)) for h in hidden])

    def forward(
        self, obs: torch.Tensor, act: torch.Tensor, params: Sequence[torch.Tensor] | None = None
    ) -> torch.Tensor:
        """``(Q1, Q2)`` stacked, shape ``(2, batch)``.

        Args:
            params: the parameters to use in :meth:`parameters` order (e.g. detached copies, so
                that the actor's loss does not compute critic weight gradients); None = own.
        """
        w_in, b_in, *rest = list(self.parameters()) if params is None else list(params)
        n = len(self.hidden)
        weights, biases = rest[:n], rest[n:2 * n]
        x = torch.cat([obs, act], dim=-1)
        if self.layer_norm:
            return self._forward_normed(x, w_in, b_in, weights, biases, rest[2 * n:])
        h = torch.relu(torch.addmm(b_in, x, w_in))
        h = h.view(x.shape[0], 2, self.hidden[0]).transpose(0, 1)
        for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
            h = torch.baddbmm(b, h, w)
            if i < n - 1:
                h = torch.relu(h)
        return h.squeeze(-1)

    def _forward_normed(
        self,
        x: torch.Tensor,
        w_in: torch.Tensor,
        b_in: torch.Tensor,
        weights: Sequence[torch.Tensor],
        biases: Sequence[torch.Tensor],
        norms: Sequence[torch.Tensor],
    ) -> torch.Tensor:
        """The forward pass with LayerNorm before every hidden ReLU."""
        n = len(self.hidden)
        scales, shifts = norms[:n], norms[n:]

        def normed(h: torch.Tensor, i: int) -> torch.Tensor:
            h = nn.functional.layer_norm(h, (self.hidden[i],))
            return torch.relu(torch.addcmul(shifts[i], h, scales[i]))

        h = torch.addmm(b_in, x, w_in).view(x.shape[0], 2, self.hidden[0]).transpose(0, 1)
        h = normed(h, 0)
        for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
            h = torch.baddbmm(b, h, w)
            if i < n - 1:
                h = normed(h, i + 1)
        return h.squeeze(-1)
