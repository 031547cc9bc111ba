"""The reward and cost critics' regression as one stacked network with hand-written gradients.

:func:`~semdp.algos.critic_regression.regress_critics` minimises, per minibatch,
``mean((V_r - R_r)^2) + mean((V_c - R_c)^2) + l2 * sum ||W||^2`` over both critics
(docs/training.md, "Algorithms and recorded choices"). With 64x64 critics and minibatches of ~128
that is a few microseconds of arithmetic per operation and tens of microseconds of autograd
bookkeeping, and TRPO-Lag/CPO take ~800 such steps per epoch. Here the two critics, which see the
same observations, run as one batch of two networks (``baddbmm``: one kernel per layer for both) and
the backward pass is written out (the derivative of ``tanh`` is ``1 - h^2``, of ReLU ``h > 0``), so
a step is ~25 operations without a graph.

The parameters and Adam's moments are gathered once per regression from the optimiser's flat
buffer (:class:`~semdp.common.optim.FlatAdam`, order: critic_r's parameters, then critic_c's)
into the stacked order (per layer: both weights, then both biases) and scattered back after it;
the Adam step is :meth:`FlatAdam.step_buffers`. The mathematics are the autograd path's (the
same loss, joint gradient-norm clip, Adam); the numbers differ from it in the last bits (other
summation orders), as tested against autograd.

The loss is defined in :func:`semdp.algos.critic_regression.critic_loss`; this kernel is the
presets' opt-in (``gradients="written"``) and is checked against that definition when an on-policy
algorithm is built (:meth:`~semdp.algos.kernels.written.WrittenDerivatives.check_critics`: loss and
gradient on a random minibatch, to ``RTOL`` = 1e-4 of their size; they agree to ~2e-7).
Why it is kept: in one PPO-Lag update (``conf/algo/ppo_lag.yaml``, ``env=point_push1``; medians
of 5 alternating repetitions on the loaded 2-core machine, 2026-12-06) it took the update from
3.54 s to 2.99 s (1.19x) alone; with the written actor step the update is 1.37-1.67x
autograd's and 1.34-1.40x that of ``torch.compile`` of both losses (figures in
:mod:`semdp.algos.kernels.ppo_actor_step`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import nn

from semdp.algos.kernels.mlp_grads import ACTIVATION_GRADS, ACTIVATIONS, backprop_mlp, mlp_layers
from semdp.common.optim import FlatAdam


def _layers(critic: nn.Module) -> tuple[list[nn.Linear], list[type[nn.Module]]] | None:
    """The layers of ``critic.net`` if it is a one-output MLP with hand-written derivatives."""
    parts = mlp_layers(getattr(critic, "net", None))
    if parts is None or parts[0][-1].out_features != 1:
        return None
    return parts


class StackedCritics:
    """Both critics as one stacked network, bound to their optimiser's flat buffers.

    Use :meth:`build`, which returns ``None`` where the fast path does not apply (other
    architectures or optimisers: the autograd path runs them).
    """

    def __init__(
        self,
        shapes: list[tuple[int, int]],
        activations: list[type[nn.Module]],
        index: torch.Tensor,
        optimizer: FlatAdam,
    ) -> None:
        self.shapes, self.activations = shapes, activations
        self.index, self.optimizer = index, optimizer

    @classmethod
    def build(
        cls, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer
    ) -> StackedCritics | None:
        """The stacked form of two critics of the same MLP shape trained by one ``FlatAdam``
        over ``[*critic_r.parameters(), *critic_c.parameters()]``; ``None`` otherwise."""
        if type(optimizer) is not FlatAdam:
            return None
        parts = _layers(critic_r), _layers(critic_c)
        if parts[0] is None or parts[1] is None:
            return None
        (lin_r, act_r), (lin_c, act_c) = parts
        shapes = [(m.out_features, m.in_features) for m in lin_r]
        if act_r != act_c or shapes != [(m.out_features, m.in_features) for m in lin_c]:
            return None
        params = [*critic_r.parameters(), *critic_c.parameters()]
        own = optimizer.param_groups[0]["params"]
        if len(own) != len(params) or any(a is not b for a, b in zip(own, params, strict=False)):
            return None
        if any(p.dtype != params[0].dtype for p in params):
            return None
        # offsets of each parameter in the optimiser's flat buffer
        offsets, start = [], 0
        for p in params:
            offsets.append(start)
            start += p.numel()
        half = len(params) // 2
        blocks = []
        for layer in range(len(shapes)):
            for kind in (0, 1):  # weights, then biases
                for critic in (0, 1):
                    i = critic * half + 2 * layer + kind
                    blocks.append(torch.arange(offsets[i], offsets[i] + params[i].numel()))
        return cls(shapes, act_r, torch.cat(blocks), optimizer)

    def _views(self, flat: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """Per layer ``(W, b)`` views of a stacked buffer: ``W (2, out, in)``, ``b (2, out)``."""
        views, start = [], 0
        for out, inp in self.shapes:
            w = flat[start:start + 2 * out * inp].view(2, out, inp)
            start += 2 * out * inp
            b = flat[start:start + 2 * out].view(2, out)
            start += 2 * out
            views.append((w, b))
        return views

    @torch.no_grad()
    def regress(
        self,
        obs: torch.Tensor,
        ret_r: torch.Tensor,
        ret_c: torch.Tensor,
        perms: Sequence[torch.Tensor],
        minibatch: int,
        l2: float,
        max_grad_norm: float | None,
        stop: Callable[[], bool] | None = None,
    ) -> tuple[float, float] | None:
        """:func:`~semdp.algos.critic_regression.regress_critics` on the stacked network
        (its arguments, with the targets as three tensors, and its return value)."""
        flat, exp_avg, exp_avg_sq = self.optimizer.buffers()
        index = self.index
        params, m, v = flat[index], exp_avg[index], exp_avg_sq[index]
        grad = torch.empty_like(params)
        layers, grads = self._views(params), self._views(grad)
        decay = torch.zeros_like(params)  # d(l2 * sum W^2)/dW = 2 l2 W on the weights only
        for w, _ in self._views(decay):
            w.fill_(2.0 * l2)
        acts = [ACTIVATIONS[a] for a in self.activations]
        act_grads = [ACTIVATION_GRADS[a] for a in self.activations]
        returns = torch.stack((ret_r, ret_c))  # (2, N)
        n = obs.shape[0]
        err = torch.zeros(2, 0)
        try:
            for perm in perms:
                all_obs, all_ret = obs[perm], returns[:, perm]
                for start in range(0, n, minibatch):
                    if stop is not None and stop():
                        return None
                    err = self._minibatch_grad(layers, grads, acts, act_grads,
                                               all_obs[start:start + minibatch],
                                               all_ret[:, start:start + minibatch])
                    grad.addcmul_(params, decay)
                    if max_grad_norm is not None:
                        total = torch.linalg.vector_norm(grad)
                        grad.mul_(torch.clamp(float(max_grad_norm) / (total + 1e-6), max=1.0))
                    self.optimizer.step_buffers(params, grad, m, v)
        finally:  # also when stopped: the critics as far as they got, as on the autograd path
            flat.index_copy_(0, index, params)
            exp_avg.index_copy_(0, index, m)
            exp_avg_sq.index_copy_(0, index, v)
        if err.numel() == 0:
            return 0.0, 0.0
        losses = (err * err).mean(1)
        return float(losses[0]), float(losses[1])

    @staticmethod
    def _minibatch_grad(
        layers: list[tuple[torch.Tensor, torch.Tensor]],
        grads: list[tuple[torch.Tensor, torch.Tensor]],
        acts: Sequence[Callable[[torch.Tensor], torch.Tensor]],
        act_grads: Sequence[Callable[[torch.Tensor], torch.Tensor]],
        x: torch.Tensor,
        ret: torch.Tensor,
    ) -> torch.Tensor:
        """Both squared errors' gradient (without the ``l2`` term) into ``grads``; the errors
        ``(2, B)``."""
        batch = x.shape[0]
        h = x.expand(2, batch, x.shape[1])
        hidden, slopes = [h], []
        for (w, b), act, slope in zip(layers[:-1], acts, act_grads, strict=True):
            h = act(torch.baddbmm(b.unsqueeze(1), h, w.transpose(1, 2)))
            hidden.append(h)
            slopes.append(slope(h))
        w_out, b_out = layers[-1]
        value = torch.baddbmm(b_out.unsqueeze(1), h, w_out.transpose(1, 2))
        err = value.squeeze(-1) - ret
        # d loss / d value, (2, B, 1), back through both networks
        backprop_mlp((err * (2.0 / batch)).unsqueeze(-1), hidden, [w for w, _ in layers], slopes,
                     grads)
        return err

    @torch.no_grad()
    def loss_and_grad(
        self, obs: torch.Tensor, ret_r: torch.Tensor, ret_c: torch.Tensor, l2: float
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The regression's minibatch loss on ``(obs, ret_r, ret_c)`` (both squared errors plus
        ``l2`` times the squared weights) and its gradient in the optimiser's parameter order
        (critic_r's, then critic_c's), unclipped; the parameters are not touched."""
        flat = self.optimizer.buffers()[0]
        params = flat[self.index]
        grad = torch.empty_like(params)
        layers, grads = self._views(params), self._views(grad)
        err = self._minibatch_grad(layers, grads, [ACTIVATIONS[a] for a in self.activations],
                                   [ACTIVATION_GRADS[a] for a in self.activations], obs,
                                   torch.stack((ret_r, ret_c)))
        weight_sq = sum((w * w).sum() for w, _ in layers)
        for (w, _), (gw, _) in zip(layers, grads, strict=True):
            gw.add_(w, alpha=2.0 * l2)
        out = torch.empty_like(flat)
        out.index_copy_(0, self.index, grad)
        return (err * err).mean(1).sum() + l2 * weight_sq, out
