"""Critic regression in a forked helper process, concurrent with the actor update.

The actor update (PPO's clipped passes, TRPO's and CPO's natural-gradient step) never reads the
critics, so their regression (:func:`~semdp.common.critic_regression.regress_critics`) can run
on the second core meanwhile (semdp/README.md, "Throughput"). Each request carries the critics'
and the optimiser's state, the targets and the permutations; the reply carries the new states
and the losses, which the trainer loads: the result is bit-identical to regressing in the
trainer. A request can be cancelled (PPO starts one before it knows which permutations the
critics will get; see :class:`~semdp.algos.ppo.PPO`).
"""

from __future__ import annotations

import mmap
from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from semdp.common.critic_regression import CriticTargets, regress_critics
from solvers.workers import Helper


def _numpy_state(state: Any) -> Any:
    """A state dict with tensors as numpy arrays (plain pickle, no shared-memory handles)."""
    if isinstance(state, torch.Tensor):
        return ("tensor", state.detach().numpy().copy(), str(state.dtype))
    if isinstance(state, dict):
        return {k: _numpy_state(v) for k, v in state.items()}
    if isinstance(state, list | tuple):
        return type(state)(_numpy_state(v) for v in state)
    return state


def _torch_state(state: Any) -> Any:
    if isinstance(state, tuple) and len(state) == 3 and state[0] == "tensor":
        return torch.from_numpy(state[1])
    if isinstance(state, dict):
        return {k: _torch_state(v) for k, v in state.items()}
    if isinstance(state, list | tuple):
        return type(state)(_torch_state(v) for v in state)
    return state


class _Server:
    """The helper's side: load the states, regress, reply with the new states."""

    def __init__(
        self,
        critic_r: nn.Module,
        critic_c: nn.Module,
        optimizer: torch.optim.Optimizer,
        cancel: mmap.mmap,
    ) -> None:
        self.critic_r, self.critic_c, self.optimizer = critic_r, critic_c, optimizer
        self.cancel = cancel

    def __call__(self, job: dict[str, Any]) -> dict[str, Any] | None:
        """The new states and the losses, or None when the regression was cancelled."""
        self.critic_r.load_state_dict(_torch_state(job["critic_r"]))
        self.critic_c.load_state_dict(_torch_state(job["critic_c"]))
        self.optimizer.load_state_dict(_torch_state(job["optimizer"]))
        obs, ret_r, ret_c = (torch.from_numpy(a) for a in job["targets"])
        perms = [torch.from_numpy(p) for p in job["perms"]]
        losses = regress_critics(
            self.critic_r, self.critic_c, self.optimizer, CriticTargets(obs, ret_r, ret_c),
            perms, job["minibatch"], job["l2"], job["max_grad_norm"],
            stop=lambda: self.cancel[0] == 1, autograd=job["autograd"],
        )
        if losses is None:
            return None
        return {
            "critic_r": _numpy_state(self.critic_r.state_dict()),
            "critic_c": _numpy_state(self.critic_c.state_dict()),
            "optimizer": _numpy_state(self.optimizer.state_dict()),
            "losses": losses,
        }


class CriticWorker:
    """A helper that regresses copies of ``critic_r`` and ``critic_c`` on request.

    Args:
        critic_r, critic_c, optimizer: the trainer's critics and their optimiser (the helper
            works on its forked copies and loads the trainer's state with every request).
    """

    def __init__(
        self, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer
    ) -> None:
        self._cancel = mmap.mmap(-1, 1)
        self._worker = Helper.fork(_Server(critic_r, critic_c, optimizer, self._cancel),
                                   name="semdp-critics")
        self._pending = False

    def submit(
        self,
        critic_r: nn.Module,
        critic_c: nn.Module,
        optimizer: torch.optim.Optimizer,
        targets: CriticTargets,
        perms: Sequence[torch.Tensor],
        minibatch: int,
        l2: float,
        max_grad_norm: float | None,
        autograd: bool = False,
    ) -> None:
        """Start a regression from the given critics' current state (arguments as
        :func:`~semdp.common.critic_regression.regress_critics`)."""
        if self._pending:
            raise RuntimeError("a critic regression is already running")
        self._cancel[0] = 0
        job = {
            "critic_r": _numpy_state(critic_r.state_dict()),
            "critic_c": _numpy_state(critic_c.state_dict()),
            "optimizer": _numpy_state(optimizer.state_dict()),
            "targets": [t.numpy() for t in targets],
            "perms": [p.numpy() for p in perms],
            "minibatch": int(minibatch), "l2": float(l2), "max_grad_norm": max_grad_norm,
            "autograd": bool(autograd),
        }  # fmt: skip
        self._worker.send(job)
        self._pending = True

    def cancel(self) -> None:
        """Abandon the running regression (its reply is discarded)."""
        if self._pending:
            self._cancel[0] = 1
            self._receive()

    def _receive(self) -> dict[str, Any] | None:
        self._pending = False
        return self._worker.receive()

    def result(
        self, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer
    ) -> tuple[float, float]:
        """Wait for the regression, load its result into the given modules; return the losses.

        Raises:
            RuntimeError: if none is running, it was cancelled or it failed.
        """
        if not self._pending:
            raise RuntimeError("no critic regression is running")
        out = self._receive()
        if out is None:
            raise RuntimeError("the critic regression was cancelled")
        critic_r.load_state_dict(_torch_state(out["critic_r"]))
        critic_c.load_state_dict(_torch_state(out["critic_c"]))
        optimizer.load_state_dict(_torch_state(out["optimizer"]))
        return out["losses"]

    def close(self) -> None:
        """Stop the helper."""
        if self._pending:
            self.cancel()
        self._worker.close()
