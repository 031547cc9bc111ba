"""The followers of several SEMDP envs acting in one batched forward per low-level step (thesis
§3.5.3, App. B.2.2; the lockstep loop of :class:`semdp.embedded.vector.LockstepVectorEnv`).

A goal-conditioned follower is a small MLP (Point: 14 -> 128 -> 128 -> 2). One torch call per
env and low-level step costs far more in dispatch than in arithmetic, so the followers of envs
that share weights are evaluated together, in NumPy, on the stacked inputs.
"""

from __future__ import annotations

import math
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
        self._columns: np.ndarray | None = None
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
        return [row.copy() for row in self.mlp(self.network_inputs(indices, inputs))]

    def network_inputs(self, indices: Sequence[int],
                       inputs: Sequence[FollowerInputs]) -> np.ndarray:
        """The batched followers' inputs, stacked (row ``j``: :meth:`PolicyFollower.network_input`
        of follower ``indices[j]`` for ``inputs[j]``, the same floats): the sensor columns, the
        ego-frame goal vector and the normalisation as one array operation each."""
        first = self.followers[indices[0]]
        assert isinstance(first, PolicyFollower)
        columns = self._sensor_columns(first)
        # rows stacked by np.array (the arrays of np.stack, without its per-call checks)
        obs = np.array([args[0] for args in inputs])
        positions = np.array([args[1] for args in inputs], dtype=np.float64)
        targets = np.array([args[3] for args in inputs], dtype=np.float64)
        cos = np.array([math.cos(args[2]) for args in inputs])
        sin = np.array([math.sin(args[2]) for args in inputs])
        error = targets - positions  # world frame; world_to_ego's rotation, row by row
        x = np.empty((len(inputs), len(columns) + 2), dtype=np.float32)
        x[:, :len(columns)] = obs[:, columns]
        x[:, -2] = cos * error[:, 0] + sin * error[:, 1]
        x[:, -1] = -sin * error[:, 0] + cos * error[:, 1]
        x = (x - first.obs_mean) / first.obs_std
        # np.clip's operation (NaN kept) without its wrappers
        return np.minimum(np.maximum(x, -first.obs_clip), first.obs_clip)

    def _sensor_columns(self, follower: PolicyFollower) -> np.ndarray:
        """The columns of an env's flat observation that make up the followers' sensors."""
        if self._columns is None:
            columns = [f.sensor_columns() for f in self.followers]  # type: ignore[union-attr]
            if any(not np.array_equal(c, columns[0]) for c in columns):
                raise ValueError("batched followers must read the same observation columns")
            self._columns = follower.sensor_columns()
        return self._columns
