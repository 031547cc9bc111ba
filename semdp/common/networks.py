"""Actor and critic networks (defaults: docs/training.md, "Algorithms and recorded choices").

On-policy: separate MLPs for the Gaussian actor (state-independent learnable ``log_std``), the
reward critic and the cost critic, 64x64 tanh, orthogonal init (CleanRL gains: sqrt(2) hidden,
0.01 actor head, 1.0 critic head). SAC: tanh-squashed Gaussian actor with ``log_std`` squashed
into [-5, 2], 256x256 ReLU (its twin Q networks: :mod:`semdp.algos.sac.twin_q`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import nn
from torch.distributions import Normal

ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def mlp(
    in_dim: int,
    hidden_sizes: Sequence[int],
    out_dim: int,
    activation: str = "tanh",
    out_gain: float = 1.0,
) -> nn.Sequential:
    """A fully connected network with orthogonal initialisation and zero biases."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {activation!r}")
    layers: list[nn.Module] = []
    sizes = [in_dim, *hidden_sizes]
    for a, b in itertools.pairwise(sizes):
        linear = nn.Linear(a, b)
        nn.init.orthogonal_(linear.weight, math.sqrt(2))
        nn.init.zeros_(linear.bias)
        layers += [linear, ACTIVATIONS[activation]()]
    head = nn.Linear(sizes[-1], out_dim)
    nn.init.orthogonal_(head.weight, out_gain)
    nn.init.zeros_(head.bias)
    layers.append(head)
    return nn.Sequential(*layers)


def forward_mlp(net: nn.Sequential, x: torch.Tensor) -> torch.Tensor:
    """``net(x)`` calling each layer's function directly: the operations of ``Linear``'s,
    ``Tanh``'s and ``ReLU``'s ``forward`` (other layers are called as modules), without the
    per-module call overhead that costs more than these small layers' arithmetic."""
    for layer in net:
        if type(layer) is nn.Linear:
            x = F.linear(x, layer.weight, layer.bias)
        elif type(layer) is nn.Tanh:
            x = torch.tanh(x)
        elif type(layer) is nn.ReLU and not layer.inplace:
            x = torch.relu(x)
        else:
            x = layer(x)
    return x


class GaussianActor(nn.Module):
    """Diagonal Gaussian policy with a state-independent learnable ``log_std``."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden_sizes: Sequence[int] = (64, 64),
        activation: str = "tanh",
        log_std_init: float = 0.0,
    ) -> None:
        super().__init__()
        self.mean_net = mlp(obs_dim, hidden_sizes, act_dim, activation, out_gain=0.01)
        self.log_std = nn.Parameter(torch.full((act_dim,), float(log_std_init)))

    def distribution(self, obs: torch.Tensor) -> Normal:
        """pi(.|obs).

        Without argument validation: its checks (finite mean, positive scale, real samples)
        cost more than the forward pass of these small networks; a NaN policy still fails at
        the env's action check.
        """
        return Normal(self.mean(obs), self.log_std.exp().expand(obs.shape[0], -1),
                      validate_args=False)

    def mean(self, obs: torch.Tensor) -> torch.Tensor:
        """The mean action (the deterministic policy), shape ``(batch, act_dim)``."""
        return forward_mlp(self.mean_net, obs)

    def log_prob(self, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Summed log-density of ``actions`` (shape ``(batch,)``)."""
        return self.distribution(obs).log_prob(actions).sum(-1)


class ValueCritic(nn.Module):
    """State-value function V(s) (reward or cost)."""

    def __init__(
        self, obs_dim: int, hidden_sizes: Sequence[int] = (64, 64), activation: str = "tanh"
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden_sizes, 1, activation, out_gain=1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """V(obs), shape ``(batch,)``."""
        return forward_mlp(self.net, obs).squeeze(-1)


class SquashedGaussianActor(nn.Module):
    """tanh-squashed Gaussian policy for SAC; actions in [-1, 1]."""

    LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden_sizes: Sequence[int] = (256, 256),
        activation: str = "relu",
    ) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden_sizes, 2 * act_dim, activation, out_gain=0.01)

    def head(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The network's two halves: the pre-squash mean and the raw (unsquashed) log-std."""
        mean, raw_log_std = forward_mlp(self.net, obs).chunk(2, dim=-1)
        return mean, raw_log_std

    def forward(
        self, obs: torch.Tensor, deterministic: bool = False, noise: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(action, log_prob)`` of the squashed policy at ``obs``: the one sampler of this
        actor (:meth:`reparameterised`), with standard-normal ``noise`` drawn from torch's
        generator unless given, or none (the mode, ``tanh(mean)``) when ``deterministic``."""
        mean, raw_log_std = self.head(obs)
        if deterministic:
            noise = torch.zeros_like(mean)
        elif noise is None:  # Normal.rsample's draw: normal_() on a fresh tensor
            noise = torch.empty(mean.shape, dtype=mean.dtype, device=mean.device).normal_()
        sample = self.reparameterised(mean, raw_log_std, noise)
        return sample.action, sample.log_prob

    @classmethod
    def reparameterised(
        cls, mean: torch.Tensor, raw_log_std: torch.Tensor, noise: torch.Tensor,
    ) -> SquashedSample:
        """The squashed sample with its standard-normal ``noise``: ``u = mean +
        std * noise``, ``log N(u) = -noise^2 / 2 - log std - log(2 pi) / 2`` (the SAC
        learner's form, one formula for its autograd and its written gradients).

        The order of the operations is part of the contract: under autograd, ``u``'s three
        gradients are accumulated in the reverse order of its uses (``log 2 - u``, then
        ``-2 u``, then ``tanh(u)``), which the written backward of
        :mod:`semdp.algos.kernels.sac_written` reproduces bit for bit."""
        span = cls.LOG_STD_MAX - cls.LOG_STD_MIN
        tanh_raw = torch.tanh(raw_log_std)
        log_std = cls.LOG_STD_MIN + 0.5 * span * (tanh_raw + 1.0)
        std = log_std.exp()
        pre_tanh = mean + std * noise
        log2_minus = math.log(2.0) - pre_tanh
        neg2 = -2.0 * pre_tanh
        correction = 2.0 * (log2_minus - nn.functional.softplus(neg2))
        log_prob = (-0.5 * noise.square() - log_std - 0.5 * math.log(2.0 * math.pi)
                    - correction).sum(-1)
        return SquashedSample(torch.tanh(pre_tanh), log_prob, tanh_raw, std, neg2)


class SquashedSample(NamedTuple):
    """:meth:`SquashedGaussianActor.reparameterised`'s action and log-probability, and the
    intermediate values a written backward needs."""

    action: torch.Tensor
    log_prob: torch.Tensor
    tanh_raw: torch.Tensor
    std: torch.Tensor
    neg2_pre_tanh: torch.Tensor
