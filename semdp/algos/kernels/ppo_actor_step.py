"""PPO's clipped-surrogate minibatch step for the Gaussian actor, derivatives written out.

Per minibatch of ``B`` samples, PPO (thesis Eq. 2.6; docs/training.md, "Algorithms and
recorded choices") minimises ``-mean(min(r A, clip(r, 1 - eps, 1 + eps) A)) - ent_coef *
entropy`` with
``r = exp(log pi(a|s) - log pi_old(a|s))``, clips the gradient norm and takes an Adam step. For the
diagonal Gaussian with a state-independent ``log_std`` the derivatives are short:

* d loss / d log pi_i = -A_i r_i / B where the unclipped term is the minimum (or the two are
  equal, i.e. r inside the clip range), else 0 (autograd gives the same: ``min`` splits a tie
  in halves and ``clamp`` passes its own half inside the range);
* d log pi / d mu = (a - mu) / sigma^2, d log pi / d log_std = (a - mu)^2 / sigma^2 - 1, and the
  entropy's d / d log_std = 1 per dimension;
* d / d mu goes back through the mean MLP (:mod:`semdp.algos.kernels.mlp_grads`).

So a step is ~40 tensor operations without a graph. Its Adam step is the actor's
:class:`~semdp.common.optim.FlatAdam` on its own buffers; the numbers equal autograd's up to
rounding (tested).

The loss is defined in :meth:`semdp.algos.ppo.PPO.actor_loss`; this kernel is the presets' opt-in
(``gradients="written"``) and is checked against that definition when PPO is built
(:meth:`~semdp.algos.kernels.written.WrittenDerivatives.check_ppo`: loss, entropy and gradient on a
random minibatch, to ``RTOL`` = 1e-4 of their size; they agree to ~2e-7).

Why it is kept (measured 2026-12-06 on this project's 2-core machine, loaded by other runs:
medians of 5 alternating repetitions of one PPO-Lag update, ``conf/algo/ppo_lag.yaml`` with
``env=point_push1``, 10,000 steps, 10 passes x 32 minibatches, actor and critics; two series):
autograd 4.03 / 2.49 s, ``torch.compile`` of ``PPO.actor_loss`` and the critics' loss
3.40 / 2.44 s (after 86 s of compilation with a cold inductor cache / 8 s with a warm one),
written kernels 2.42 / 1.82 s, i.e. 1.67x / 1.37x autograd and 1.40x / 1.34x the compiled loss.
Alone, this actor step took the update from 3.54 s to 2.94 s (1.21x) in a third series.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from semdp.algos.kernels.mlp_grads import (
    ACTIVATION_GRADS,
    ACTIVATIONS,
    backprop_mlp,
    gaussian_actor_layers,
)
from semdp.common.optim import FlatAdam

_HALF_LOG_2PI = 0.5 * math.log(2 * math.pi)


class PPOActorStep:
    """Clipped-surrogate steps of a Gaussian actor (``log_std`` vector, then a ``mean_net`` MLP,
    in parameter order) trained by a :class:`FlatAdam` over ``actor.parameters()``.

    Use :meth:`build`, which returns ``None`` where this does not apply (the autograd step runs
    there).
    """

    def __init__(
        self, shapes: list[tuple[int, int]], activations: list[type[nn.Module]],
        act_dim: int, optimizer: FlatAdam,
    ) -> None:
        self.shapes, self.act_dim, self.optimizer = shapes, act_dim, optimizer
        self.acts = [ACTIVATIONS[a] for a in activations]
        self.slopes = [ACTIVATION_GRADS[a] for a in activations]
        self.grad = torch.zeros(act_dim + sum(o * i + o for o, i in shapes))
        #: ``log_std`` and per-layer ``(W, b)`` views of :attr:`grad`, filled by each step.
        self.grad_views = self._views(self.grad)

    @classmethod
    def build(cls, actor: nn.Module, optimizer: torch.optim.Optimizer) -> PPOActorStep | None:
        """The step for ``actor`` and ``optimizer``, or ``None`` if they are not of that form."""
        if type(optimizer) is not FlatAdam:
            return None
        parts = gaussian_actor_layers(actor)
        if parts is None:
            return None
        own, params = optimizer.param_groups[0]["params"], list(actor.parameters())
        if len(own) != len(params) or any(a is not b for a, b in zip(own, params, strict=False)):
            return None
        linears, activations = parts
        shapes = [(m.out_features, m.in_features) for m in linears]
        return cls(shapes, activations, actor.log_std.numel(), optimizer)

    def _views(self, flat: torch.Tensor) -> tuple[torch.Tensor,
                                                   list[tuple[torch.Tensor, torch.Tensor]]]:
        """``log_std`` and the per-layer ``(W, b)`` views of a buffer in parameter order."""
        layers, start = [], self.act_dim
        for out, inp in self.shapes:
            w = flat[start:start + out * inp].view(out, inp)
            b = flat[start + out * inp:start + out * inp + out]
            layers.append((w, b))
            start += out * inp + out
        return flat[:self.act_dim], layers

    @torch.no_grad()
    def step(
        self,
        obs: torch.Tensor,
        actions: torch.Tensor,
        old_log_probs: torch.Tensor,
        adv: torch.Tensor,
        clip_range: float,
        ent_coef: float,
        max_grad_norm: float | None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One Adam step on the minibatch; return ``(loss_pi, entropy)`` before the step."""
        flat, exp_avg, exp_avg_sq = self.optimizer.buffers()
        loss, entropy = self.loss_and_grad(obs, actions, old_log_probs, adv, clip_range, ent_coef)
        if max_grad_norm is not None:
            total = torch.linalg.vector_norm(self.grad)
            self.grad.mul_(torch.clamp(float(max_grad_norm) / (total + 1e-6), max=1.0))
        self.optimizer.step_buffers(flat, self.grad, exp_avg, exp_avg_sq)
        return loss, entropy

    @torch.no_grad()
    def loss_and_grad(
        self, obs: torch.Tensor, actions: torch.Tensor, old_log_probs: torch.Tensor,
        adv: torch.Tensor, clip_range: float, ent_coef: float,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(loss_pi, entropy)`` at the optimiser's parameters, the loss's gradient (in
        parameter order, unclipped) left in :attr:`grad`; the parameters are not touched."""
        flat = self.optimizer.buffers()[0]
        log_std, layers = self._views(flat)
        g_log_std, grads = self.grad_views
        batch = obs.shape[0]
        inputs, slopes = [obs], []
        h = obs
        for (w, b), act, slope in zip(layers[:-1], self.acts, self.slopes, strict=True):
            h = act(torch.addmm(b, h, w.t()))
            inputs.append(h)
            slopes.append(slope(h))
        w_out, b_out = layers[-1]
        mean = torch.addmm(b_out, h, w_out.t())
        inv_var = torch.exp(-2.0 * log_std)
        diff = actions - mean
        scaled = diff * inv_var  # (a - mu) / sigma^2 = d log pi / d mu
        sq = diff * scaled  # (a - mu)^2 / sigma^2
        log_std_sum = log_std.sum()
        log_prob = -0.5 * sq.sum(-1) - log_std_sum - self.act_dim * _HALF_LOG_2PI
        ratio = torch.exp(log_prob - old_log_probs)
        unclipped = ratio * adv
        clipped = ratio.clamp(1 - clip_range, 1 + clip_range) * adv
        active = unclipped <= clipped
        entropy = (0.5 + _HALF_LOG_2PI) * self.act_dim + log_std_sum
        loss = -torch.minimum(unclipped, clipped).mean() - ent_coef * entropy
        # d loss / d log pi, per sample
        d_log_prob = torch.where(active, unclipped, 0.0).mul_(-1.0 / batch).unsqueeze(-1)
        torch.sum(d_log_prob * (sq - 1.0), 0, out=g_log_std)
        g_log_std.sub_(ent_coef)
        # d loss / d mu, back through the mean network
        backprop_mlp(d_log_prob * scaled, inputs, [w for w, _ in layers], slopes, grads)
        return loss, entropy
