"""Critic regression in a forked helper process, concurrent with the actor update.

The actor update (PPO's clipped passes, TRPO's and CPO's natural-gradient step) never reads the
critics, so their regression (:func:`~semdp.common.critic_regression.regress_critics`) can run
on the second core meanwhile (semdp/README.md, "Throughput"). Each request carries the critics'
and the optimiser's state, the targets and the permutations; the reply carries the new states
and the losses, which the trainer loads: the result is bit-identical to regressing in the
trainer. A request can be cancelled (PPO starts one before it knows which permutations the
critics will get; see :class:`~semdp.algos.ppo.PPO`).

Where the actor update is short (TRPO's and CPO's single natural-gradient step), the trainer
would mostly wait for the helper; there the regression is split instead
(:meth:`CriticWorker.submit_half`): the helper regresses the reward critic while the trainer,
after its actor step, regresses the cost critic, and the two exchange their gradient norms once
per minibatch over a second pipe for the joint clip
(:func:`~semdp.common.critic_regression.regress_critic_half`), again bit for bit the joint
regression.
"""

from __future__ import annotations

import copy
import mmap
import multiprocessing as mp
import os
import pickle
import traceback
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import torch
from torch import nn

from semdp.common.critic_regression import (
    CriticTargets,
    regress_critic_half,
    regress_critics,
)
from semdp.common.forked_worker import ForkedWorker
from semdp.common.optim import FlatAdam

_OK, _ERROR, _CANCELLED = b"d", b"e", b"c"
#: Seconds between the helper's checks for a cancellation while it waits for the trainer.
_POLL_S = 0.2


def optimizer_slice(state: dict[str, Any], first: int, count: int) -> dict[str, Any]:
    """The state dict of an Adam over parameters ``first .. first + count - 1`` of ``state``
    (torch's Adam layout, one parameter group)."""
    group = {k: v for k, v in state["param_groups"][0].items() if k != "params"}
    group["params"] = list(range(count))
    sub = {j: state["state"][first + j] for j in range(count) if first + j in state["state"]}
    return {"state": sub, "param_groups": [group]}


def optimizer_join(state: dict[str, Any], parts: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """``state`` with its per-parameter entries replaced by ``parts`` in order (the inverse
    of :func:`optimizer_slice` over consecutive slices)."""
    merged: dict[int, Any] = {}
    offset = 0
    for part in parts:
        for j, entry in part["state"].items():
            merged[offset + int(j)] = entry
        offset += len(part["param_groups"][0]["params"])
    return {"state": merged, "param_groups": state["param_groups"]}


def exchange_over(conn: Connection, tag: int, stop: Any = None) -> Any:
    """``exchange(own norms) -> other norms`` over ``conn``: float32 bytes after an 8-byte job
    ``tag`` (messages of another job, left by a cancelled one, are skipped); waiting is abandoned
    (None) as soon as ``stop()`` is true."""
    prefix = int(tag).to_bytes(8, "little")

    def exchange(own: torch.Tensor) -> torch.Tensor | None:
        conn.send_bytes(prefix + own.detach().numpy().astype(np.float32).tobytes())
        while True:
            if stop is not None:
                while not conn.poll(_POLL_S):
                    if stop():
                        return None
            message = conn.recv_bytes()
            if message[:8] == prefix:
                other = np.frombuffer(message[8:], dtype=np.float32).copy()
                return torch.from_numpy(other).to(own.dtype)

    return exchange


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
        side: Connection,
    ) -> None:
        self.critic_r, self.critic_c, self.optimizer = critic_r, critic_c, optimizer
        self.cancel, self.side = cancel, side
        self.parent: int | None = None  # the trainer's pid, read in the helper
        self._half_optimizer: FlatAdam | None = None

    def _stopped(self) -> bool:
        return self.cancel[0] == 1 or os.getppid() != self.parent

    def _half(self, job: dict[str, Any]) -> bytes:
        """The reward critic's half of a split regression."""
        self.critic_r.load_state_dict(_torch_state(job["critic_r"]))
        if self._half_optimizer is None:
            self._half_optimizer = FlatAdam(self.critic_r.parameters(), lr=1e-3)
        opt = self._half_optimizer
        opt.load_state_dict(_torch_state(job["optimizer"]))
        obs, ret_r = (torch.from_numpy(a) for a in job["targets"])
        perms = [torch.from_numpy(p) for p in job["perms"]]
        loss = regress_critic_half(
            self.critic_r, opt, obs, ret_r, perms, job["minibatch"], job["l2"],
            job["max_grad_norm"], exchange_over(self.side, job["tag"], self._stopped), first=True,
        )
        if loss is None:
            return _CANCELLED
        return _OK + pickle.dumps({
            "critic_r": _numpy_state(self.critic_r.state_dict()),
            "optimizer": _numpy_state(opt.state_dict()),
            "loss": loss,
        })

    def __call__(self, request: bytes) -> bytes:
        if self.parent is None:
            self.parent = os.getppid()
        try:
            job = pickle.loads(request)
            if job.get("half"):
                return self._half(job)
            self.critic_r.load_state_dict(_torch_state(job["critic_r"]))
            self.critic_c.load_state_dict(_torch_state(job["critic_c"]))
            self.optimizer.load_state_dict(_torch_state(job["optimizer"]))
            obs, ret_r, ret_c = (torch.from_numpy(a) for a in job["targets"])
            perms = [torch.from_numpy(p) for p in job["perms"]]
            losses = regress_critics(
                self.critic_r, self.critic_c, self.optimizer, CriticTargets(obs, ret_r, ret_c),
                perms, job["minibatch"], job["l2"], job["max_grad_norm"],
                stop=lambda: self.cancel[0] == 1,
            )
            if losses is None:
                return _CANCELLED
            return _OK + pickle.dumps({
                "critic_r": _numpy_state(self.critic_r.state_dict()),
                "critic_c": _numpy_state(self.critic_c.state_dict()),
                "optimizer": _numpy_state(self.optimizer.state_dict()),
                "losses": losses,
            })
        except Exception:  # reported to the trainer, which raises it
            return _ERROR + traceback.format_exc().encode()


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
        self._side, child_side = mp.get_context("fork").Pipe()
        self._worker = ForkedWorker(
            _Server(critic_r, critic_c, optimizer, self._cancel, child_side),
            name="semdp-critics")
        child_side.close()  # the helper holds it; its death then ends the trainer's waits
        self._pending = False
        self._tag = 0

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
    ) -> None:
        """Start a regression from the given critics' current state."""
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
        }  # fmt: skip
        self._worker.send(pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL))
        self._pending = True

    def submit_half(
        self,
        critic_r: nn.Module,
        optimizer: torch.optim.Optimizer,
        targets: CriticTargets,
        perms: Sequence[torch.Tensor],
        minibatch: int,
        l2: float,
        max_grad_norm: float | None,
    ) -> None:
        """Start the reward critic's half of a split regression from the current state
        (``optimizer``: the joint one, reward critic's parameters first); the trainer then runs
        the cost critic's half with :meth:`finish_half`."""
        if self._pending:
            raise RuntimeError("a critic regression is already running")
        self._cancel[0] = 0
        self._tag += 1
        n_r = len(list(critic_r.parameters()))
        job = {
            "half": True, "tag": self._tag,
            "critic_r": _numpy_state(critic_r.state_dict()),
            "optimizer": _numpy_state(optimizer_slice(optimizer.state_dict(), 0, n_r)),
            "targets": [targets.obs.numpy(), targets.ret_r.numpy()],
            "perms": [p.numpy() for p in perms],
            "minibatch": int(minibatch), "l2": float(l2), "max_grad_norm": max_grad_norm,
        }  # fmt: skip
        self._worker.send(pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL))
        self._pending = True

    def finish_half(
        self,
        critic_r: nn.Module,
        critic_c: nn.Module,
        optimizer: torch.optim.Optimizer,
        targets: CriticTargets,
        perms: Sequence[torch.Tensor],
        minibatch: int,
        l2: float,
        max_grad_norm: float | None,
    ) -> tuple[float, float]:
        """Regress the cost critic here, beside the helper's reward critic; load both results
        and the joint optimiser state; return ``(loss_v, loss_vc)``.

        Raises:
            RuntimeError: if no half was submitted, or the helper failed or died.
        """
        if not self._pending:
            raise RuntimeError("no critic regression is running")
        full = optimizer.state_dict()
        n_r = len(list(critic_r.parameters()))
        n_c = len(list(critic_c.parameters()))
        work = copy.deepcopy(critic_c)
        opt_c = FlatAdam(work.parameters(), lr=full["param_groups"][0]["lr"],
                         betas=full["param_groups"][0]["betas"],
                         eps=full["param_groups"][0]["eps"])
        opt_c.load_state_dict(optimizer_slice(full, n_r, n_c))
        try:
            loss_vc = regress_critic_half(
                work, opt_c, targets.obs, targets.ret_c, perms, minibatch, l2, max_grad_norm,
                exchange_over(self._side, self._tag, self._worker.has_reply), first=False,
            )
        except BaseException:
            self.cancel()  # the helper may be waiting for this half's norms
            raise
        reply = self._receive()
        if reply[:1] != _OK or loss_vc is None:
            raise RuntimeError("the split critic regression did not finish in the helper")
        out = pickle.loads(reply[1:])
        critic_r.load_state_dict(_torch_state(out["critic_r"]))
        critic_c.load_state_dict(work.state_dict())
        optimizer.load_state_dict(
            optimizer_join(full, [_torch_state(out["optimizer"]), opt_c.state_dict()]))
        return out["loss"], loss_vc

    def cancel(self) -> None:
        """Abandon the running regression (its reply is discarded)."""
        if self._pending:
            self._cancel[0] = 1
            self._receive()

    def _receive(self) -> bytes:
        self._pending = False
        reply = self._worker.receive()
        if reply[:1] == _ERROR:
            raise RuntimeError(f"critic helper process failed:\n{reply[1:].decode()}")
        return reply

    def result(
        self, critic_r: nn.Module, critic_c: nn.Module, optimizer: torch.optim.Optimizer
    ) -> tuple[float, float]:
        """Wait for the regression, load its result into the given modules; return the losses.

        Raises:
            RuntimeError: if none is running, it was cancelled or it failed.
        """
        if not self._pending:
            raise RuntimeError("no critic regression is running")
        reply = self._receive()
        if reply[:1] != _OK:
            raise RuntimeError("the critic regression was cancelled")
        out = pickle.loads(reply[1:])
        critic_r.load_state_dict(_torch_state(out["critic_r"]))
        critic_c.load_state_dict(_torch_state(out["critic_c"]))
        optimizer.load_state_dict(_torch_state(out["optimizer"]))
        return out["losses"]

    def close(self) -> None:
        """Stop the helper."""
        if self._pending:
            self.cancel()
        self._worker.close()
