"""The followers of several SEMDP envs acting in one batched forward per low-level step (thesis
§3.5.3, App. B.2.2; the lockstep loop of :class:`semdp.embedded.vector.LockstepVectorEnv`).

A goal-conditioned follower is a small MLP (Point: 14 -> 128 -> 128 -> 2). One torch call per
env and low-level step costs far more in dispatch than in arithmetic, so the followers of envs
that share weights are evaluated together, in NumPy, on the stacked inputs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from semdp.embedded.follower import Follower, PolicyFollower

#: A follower's inputs for one low-level step: (obs, robot position, robot heading, target).
FollowerInputs = tuple[np.ndarray, np.ndarray, float, np.ndarray]


class _Activation:
    """A follower layer's activation in NumPy (in place on a fresh array; picklable)."""

    def __init__(self, module: torch.nn.Module) -> None:
        if isinstance(module, torch.nn.ReLU | torch.nn.Tanh):
            self.kind, self.low, self.high = type(module).__name__, 0.0, 0.0
        elif isinstance(module, torch.nn.Hardtanh):
            self.kind = "Hardtanh"
            self.low, self.high = float(module.min_val), float(module.max_val)
        else:
            raise ValueError(f"no NumPy form for follower layer {module!r}")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.kind == "ReLU":
            return np.maximum(x, 0.0, out=x)
        if self.kind == "Tanh":
            return np.tanh(x, out=x)
        return np.clip(x, self.low, self.high, out=x)


class NumpyMLP:
    """A float32 NumPy copy of a ``torch.nn.Sequential`` of Linear layers and activations."""

    def __init__(self, net: torch.nn.Sequential) -> None:
        self.layers: list[tuple[np.ndarray, np.ndarray] | _Activation] = []
        for module in net:
            if isinstance(module, torch.nn.Linear):
                weight = module.weight.detach().numpy().astype(np.float32).T.copy()
                bias = module.bias.detach().numpy().astype(np.float32).copy()
                self.layers.append((weight, bias))
            else:
                self.layers.append(_Activation(module))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Outputs for a ``(batch, in)`` float32 array."""
        for layer in self.layers:
            if isinstance(layer, tuple):
                x = x @ layer[0]
                x += layer[1]
            else:
                x = layer(x)
        return x


class FollowerBatch:
    """Acts for the followers of several envs; batched when they share one policy.

    Followers that are :class:`PolicyFollower` s loading the same weights with the same sensors
    are evaluated in one NumPy forward; any other mix (the Mass P-controller, differing weights)
    acts one by one through :meth:`Follower.act`.
    """

    def __init__(self, followers: Sequence[Follower]) -> None:
        self.followers = list(followers)
        if not self.followers:
            raise ValueError("FollowerBatch needs at least one follower")
        self.mlp: NumpyMLP | None = None
        if all(isinstance(f, PolicyFollower) for f in self.followers):
            kinds = {(str(f.weights), tuple(f.sensor_slices)) for f in self.followers}
            if len(kinds) == 1:
                self.mlp = NumpyMLP(self.followers[0].actor)

    @property
    def batched(self) -> bool:
        """Whether :meth:`act` runs one forward for all envs."""
        return self.mlp is not None

    def act(self, indices: Sequence[int], inputs: Sequence[FollowerInputs]) -> list[np.ndarray]:
        """Low-level actions of the followers ``indices`` for their ``inputs`` (same order)."""
        if self.mlp is None:
            return [self.followers[i].act(*args) for i, args in zip(indices, inputs, strict=True)]
        x = np.stack([self.followers[i].network_input(*args)  # type: ignore[union-attr]
                      for i, args in zip(indices, inputs, strict=True)]).astype(np.float32)
        return [row.copy() for row in self.mlp(x)]
