"""SAC's gradients written out: the learner's ``gradients="written"`` kernel (docs/semdp.md,
"The main job's loop"; the high level of thesis Alg. 2, trained by SAC, Haarnoja et al. 2018).

The learner's update (:class:`~semdp.algos.sac.learner.SACLearner`) is small networks on a
batch of 128: autograd's graph bookkeeping costs about as much as the arithmetic. This module
runs the same update without a graph: every forward operation of the plain path, then, for
each backward node autograd would run, the operation its derivative formula runs
(PyTorch's ``tools/autograd/derivatives.yaml``: ``addmm``/``baddbmm``/``mm`` backward,
``threshold_backward`` for ReLU, ``tanh_backward``, ``softplus_backward``, ``min`` as a
scatter, ``sum_to`` for broadcast biases), in the order autograd's engine accumulates them.
The gradients are then autograd's bit for bit (``tests/test_sac_written.py`` compares them
update by update), so a run gives the same numbers with either kernel; only the time differs.

Covers what the main job trains: the fused twin critic without LayerNorm and the ReLU
:class:`~semdp.common.networks.SquashedGaussianActor`; anything else raises.

The losses are defined once, in :class:`~semdp.algos.sac.learner.SACLearner`
(``critic_loss``, ``actor_loss``, ``alpha_loss``); a learner built with this kernel checks it
against them on a random minibatch, bit for bit (:meth:`SACLearner.check_written`), so an edit to
those losses that is not mirrored here fails at construction (turn the kernel off with
``algo.gradients=autograd``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import nn

from semdp.algos.kernels.mlp_grads import KernelMismatch, mlp_layers
from semdp.common.networks import SquashedGaussianActor

__all__ = ["ActorTape", "KernelMismatch", "TwinQTape", "actor_backward", "actor_forward",
           "actor_loss_grads", "alpha_loss_grad", "check_supported", "critic_loss_grads",
           "twin_q_backward", "twin_q_forward"]

_threshold_backward = torch.ops.aten.threshold_backward
_tanh_backward = torch.ops.aten.tanh_backward
_softplus_backward = torch.ops.aten.softplus_backward


@functools.lru_cache(maxsize=16)
def _mean_grad(rows: int, batch: int) -> torch.Tensor:
    """The gradient of a mean over ``batch`` (of each of ``rows`` rows; ``rows=0``: of a vector)
    as autograd's ``mean`` backward makes it: ones expanded, divided by the count. A constant,
    kept (read only)."""
    if rows == 0:
        return torch.ones(()).expand(batch) / batch
    return torch.ones(()).expand(rows).unsqueeze(1).expand(rows, batch) / batch


def check_supported(actor: SquashedGaussianActor, layer_norm: bool) -> None:
    """Raise if the networks are not the ones this kernel writes out."""
    if layer_norm:
        raise ValueError("gradients='written' covers the plain twin critic; critic_layer_norm "
                         "needs gradients='autograd'")
    parts = mlp_layers(actor.net)
    if parts is None or any(kind is not nn.ReLU for kind in parts[1]):
        raise ValueError("gradients='written' covers ReLU actors (Linear, ReLU, ..., Linear); "
                         f"got {[type(m).__name__ for m in actor.net]}")


# ----------------------------------------------------------------- fused twin critic
@dataclass
class TwinQTape:
    """What the critic's backward needs from its forward."""

    x: torch.Tensor  # [obs, act]
    h1: torch.Tensor  # first hidden layer after ReLU, (batch, 2 * width)
    inputs: list[torch.Tensor]  # the input of every batched layer, (2, batch, width)


def twin_q_forward(
    params: Sequence[torch.Tensor], hidden: Sequence[int], obs: torch.Tensor, act: torch.Tensor,
) -> tuple[torch.Tensor, TwinQTape]:
    """:meth:`FusedTwinQ.forward <semdp.algos.sac.twin_q.FusedTwinQ.forward>` (no LayerNorm),
    keeping what the backward needs: ``(Q1, Q2)`` as ``(2, batch)``."""
    n = len(hidden)
    w_in, b_in, *rest = params
    weights, biases = rest[:n], rest[n:2 * n]
    x = torch.cat([obs, act], dim=-1)
    h1 = torch.relu(torch.addmm(b_in, x, w_in))
    h = h1.view(x.shape[0], 2, hidden[0]).transpose(0, 1)
    inputs = []
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        inputs.append(h)
        h = torch.baddbmm(b, h, w)
        if i < n - 1:
            h = torch.relu(h)
    return h.squeeze(-1), TwinQTape(x, h1, inputs)


def twin_q_backward(
    params: Sequence[torch.Tensor], hidden: Sequence[int], tape: TwinQTape,
    grad_q: torch.Tensor, weight_grads: bool,
) -> tuple[list[torch.Tensor] | None, torch.Tensor | None]:
    """Autograd's backward of :func:`twin_q_forward` from ``grad_q`` (2, batch).

    Returns the parameter gradients in ``params`` order (``weight_grads``) or, without them,
    the gradient with respect to ``[obs, act]`` (what the actor's loss needs).
    """
    n = len(hidden)
    w_in, _, *rest = params
    weights = rest[:n]
    g = grad_q.unsqueeze(-1)
    g_w: list[torch.Tensor] = [torch.empty(0)] * n
    g_b: list[torch.Tensor] = [torch.empty(0)] * n
    for i in range(n - 1, -1, -1):
        inp = tape.inputs[i]
        if weight_grads:  # baddbmm: self summed to the bias' shape, batch2's bmm
            g_b[i] = g.sum(1, keepdim=True)
            g_w[i] = inp.transpose(1, 2).bmm(g)
        g = g.bmm(weights[i].transpose(1, 2))
        if i > 0:
            g = _threshold_backward(g, inp, 0)
    batch = tape.x.shape[0]
    g1 = _threshold_backward(g.transpose(0, 1).reshape(batch, 2 * hidden[0]), tape.h1, 0)
    if weight_grads:
        g_b_in = g1.sum(0, keepdim=True).view(2 * hidden[0])
        return [tape.x.t().mm(g1), g_b_in, *g_w, *g_b], None
    return None, g1.mm(w_in.t())


def critic_loss_grads(
    params: Sequence[torch.Tensor], hidden: Sequence[int], obs: torch.Tensor,
    actions: torch.Tensor, target: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor]]:
    """The critic loss ``sum over Q of mean((Q - target)^2)``, Q and the gradients of the loss
    with respect to ``params`` (SAC's critic update, Haarnoja et al. 2018, Eq. 5)."""
    q, tape = twin_q_forward(params, hidden, obs, actions)
    diff = q - target
    loss = diff.square().mean(1).sum()
    batch = q.shape[1]
    # sum -> mean(1) -> square (pow's derivative) -> sub
    grad_q = _mean_grad(2, batch) * (2.0 * diff.pow(1.0))
    grads, _ = twin_q_backward(params, hidden, tape, grad_q, weight_grads=True)
    assert grads is not None
    return loss, q, grads


# ----------------------------------------------------------------- squashed Gaussian actor
@dataclass
class ActorTape:
    """What the actor's backward needs from its forward."""

    inputs: list[torch.Tensor]  # the input of every Linear layer
    tanh_raw: torch.Tensor
    std: torch.Tensor
    noise: torch.Tensor
    neg2_pre_tanh: torch.Tensor
    action: torch.Tensor


def actor_forward(
    actor: SquashedGaussianActor, obs: torch.Tensor, noise: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, ActorTape]:
    """:meth:`SACLearner._policy <semdp.algos.sac.learner.SACLearner._policy>`'s operations
    with the noise given (the trunk, recording each ``Linear``'s input, then
    :meth:`SquashedGaussianActor.reparameterised`): the action, its log-probability and the
    tape."""
    inputs = []
    x = obs
    for layer in actor.net:
        if type(layer) is nn.Linear:
            inputs.append(x)
            x = nn.functional.linear(x, layer.weight, layer.bias)
        else:
            x = torch.relu(x)
    mean, raw_log_std = x.chunk(2, dim=-1)
    sample = actor.reparameterised(mean, raw_log_std, noise)
    return sample.action, sample.log_prob, ActorTape(
        inputs, sample.tanh_raw, sample.std, noise, sample.neg2_pre_tanh, sample.action)


def actor_backward(
    actor: SquashedGaussianActor, tape: ActorTape, grad_action: torch.Tensor,
    grad_log_prob: torch.Tensor,
) -> list[torch.Tensor]:
    """Autograd's backward of :func:`actor_forward`: the gradients of the actor's parameters
    (``actor.parameters()`` order) from those of the action and the log-probability."""
    span = actor.LOG_STD_MAX - actor.LOG_STD_MIN
    g_lp = grad_log_prob.unsqueeze(-1).expand(tape.action.shape)  # sum(-1)
    g_corr = -g_lp  # log_prob = ... - correction
    g_c4 = g_corr * 2.0
    g_softplus = _softplus_backward(-g_c4, tape.neg2_pre_tanh, 1.0, 20.0)
    # pre_tanh's three uses, accumulated in the order autograd's engine runs them
    g_pre = _tanh_backward(grad_action, tape.action)
    g_pre = g_pre + g_softplus * -2.0
    g_pre = g_pre + (-g_c4)
    g_std = g_pre * tape.noise
    g_log_std = -g_lp + g_std * tape.std
    g_raw = _tanh_backward(g_log_std * (0.5 * span), tape.tanh_raw)
    g = torch.cat([g_pre, g_raw], dim=-1)
    linears = [m for m in actor.net if type(m) is nn.Linear]
    grads: list[torch.Tensor] = []
    for i in range(len(linears) - 1, -1, -1):
        inp = tape.inputs[i]
        grads[:0] = [g.t().mm(inp), g.sum(0, keepdim=True).view(g.shape[1])]
        if i > 0:
            g = _threshold_backward(g.mm(linears[i].weight), inp, 0)
    return grads


def actor_loss_grads(
    actor: SquashedGaussianActor, critic_params: Sequence[torch.Tensor],
    hidden: Sequence[int], obs: torch.Tensor, noise: torch.Tensor, alpha: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor]]:
    """SAC's actor loss ``mean(alpha log pi(a|s) - min(Q1, Q2)(s, a))`` with ``a``
    reparameterised by ``noise`` (Haarnoja et al. 2018, Eq. 7), the log-probabilities and the
    gradients of the loss with respect to the actor's parameters (the critic held fixed)."""
    action, log_prob, tape = actor_forward(actor, obs, noise)
    q, q_tape = twin_q_forward(critic_params, hidden, obs, action)
    q_pi = q.min(0)
    loss = (alpha * log_prob - q_pi.values).mean()
    batch = obs.shape[0]
    g_mean = _mean_grad(0, batch)
    grad_q = torch.zeros_like(q).scatter_(0, q_pi.indices.unsqueeze(0), (-g_mean).unsqueeze(0))
    _, grad_x = twin_q_backward(critic_params, hidden, q_tape, grad_q, weight_grads=False)
    assert grad_x is not None
    grad_action = grad_x.narrow(1, obs.shape[1], action.shape[1])
    grads = actor_backward(actor, tape, grad_action, g_mean * alpha)
    return loss, log_prob, grads


def alpha_loss_grad(log_prob: torch.Tensor, target_entropy: float) -> torch.Tensor:
    """The gradient of the temperature loss ``-mean(log_alpha (log pi + target entropy))``
    with respect to ``log_alpha`` (Haarnoja et al. 2018b, Eq. 18)."""
    other = log_prob + target_entropy
    return ((-_mean_grad(0, other.shape[0])) * other).sum(0, keepdim=True).view(())
