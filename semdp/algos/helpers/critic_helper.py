"""The helper-process critic runner (``parallel_critics=true``/``"auto"``): the critics regress
in a forked helper, concurrent with the actor update.

The actor update (PPO's clipped passes, TRPO's and CPO's natural-gradient step) never reads the
critics, so their regression (:func:`~semdp.algos.critic_regression.regress_critics`, handed to the
helper when it is forked) can run on the second core meanwhile. Each request carries the
critics' and the optimiser's state, the targets and the permutations; the reply carries the new
states and the losses, which the trainer loads: the result is bit-identical to regressing in the
trainer. The permutations are those torch's global generator will draw after ``skip`` more draws
(the actor passes that come first): PPO's passes stop early when the KL check fires, so a
request can be cancelled and the critics regress in the trainer instead (:class:`HelperCritics`
has the interface of the plain :class:`~semdp.algos.on_policy.LocalCritics`).
"""

from __future__ import annotations

import mmap
import time
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import torch
from torch import nn

from semdp.algos.helpers.option_probe import FasterOption
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
        regress: Callable[..., tuple[float, float] | None],
    ) -> None:
        self.critic_r, self.critic_c, self.optimizer = critic_r, critic_c, optimizer
        self.cancel, self.regress = cancel, regress

    def __call__(self, job: dict[str, Any]) -> dict[str, Any] | None:
        """The new states and the losses, or None when the regression was cancelled."""
        self.critic_r.load_state_dict(_torch_state(job["critic_r"]))
        self.critic_c.load_state_dict(_torch_state(job["critic_c"]))
        self.optimizer.load_state_dict(_torch_state(job["optimizer"]))
        obs, ret_r, ret_c = (torch.from_numpy(a) for a in job["targets"])
        perms = [torch.from_numpy(p) for p in job["perms"]]
        losses = self.regress(
            self.critic_r, self.critic_c, self.optimizer, (obs, ret_r, ret_c), perms,
            job["minibatch"], job["l2"], job["max_grad_norm"], stop=lambda: self.cancel[0] == 1,
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
        regress: the regression, ``regress(critic_r, critic_c, optimizer, (obs, ret_r, ret_c),
            perms, minibatch, l2, max_grad_norm, stop=)`` as
            :func:`~semdp.algos.critic_regression.regress_critics` with its kernel bound.
    """

    def __init__(
        self,
        critic_r: nn.Module,
        critic_c: nn.Module,
        optimizer: torch.optim.Optimizer,
        regress: Callable[..., tuple[float, float] | None],
    ) -> None:
        self._cancel = mmap.mmap(-1, 1)
        self._worker = Helper.fork(_Server(critic_r, critic_c, optimizer, self._cancel, regress),
                                   name="semdp-critics")
        self._pending = False

    def submit(
        self,
        critic_r: nn.Module,
        critic_c: nn.Module,
        optimizer: torch.optim.Optimizer,
        targets: Sequence[torch.Tensor],
        perms: Sequence[torch.Tensor],
        minibatch: int,
        l2: float,
        max_grad_norm: float | None,
    ) -> None:
        """Start a regression from the given critics' current state (arguments as
        :func:`~semdp.algos.critic_regression.regress_critics`; ``targets`` = obs, ret_r, ret_c)."""
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


class CriticOwner(Protocol):
    """What :class:`HelperCritics` reads of its on-policy algorithm."""

    critic_r: nn.Module
    critic_c: nn.Module
    critic_optimizer: torch.optim.Optimizer
    critic_iters: int
    critic_l2: float
    max_grad_norm: float | None

    def critic_minibatch(self, n: int) -> int: ...

    def update_critics(self, batch: Any) -> dict[str, float]: ...


class HelperCritics:
    """Regresses the critics in a :class:`CriticWorker` while the actor updates.

    Args:
        owner: the algorithm whose critics these are.
        regress: the regression with its kernel bound (given to the forked helper).
        mode: ``True`` (always the helper) or ``"auto"`` (``choice`` picks per update).
        choice: the measured choice between the two ways (``auto``).
    """

    def __init__(
        self,
        owner: CriticOwner,
        regress: Callable[..., tuple[float, float] | None],
        mode: bool | str,
        choice: FasterOption,
    ) -> None:
        self.owner, self.regress, self.mode, self.choice = owner, regress, mode, choice
        #: Whether the critics regress in the helper in this update (``auto``: the choice).
        self.in_helper = mode is True
        self._worker: CriticWorker | None = None
        self._start = 0.0

    def start(self, batch: Any, skip: int) -> int | None:
        """Start the regression in the helper on the permutations after ``skip`` draws of
        ``randperm(batch size)`` (the generator itself is not advanced); ``None`` when the
        critics regress in the trainer this time. The update is timed until :meth:`finish`."""
        self._start = time.perf_counter()
        if self.mode == "auto":
            self.in_helper = self.choice.choose()
        if not self.in_helper:
            return None
        o = self.owner
        n = batch.obs.shape[0]
        generator = torch.Generator()
        generator.set_state(torch.get_rng_state())
        for _ in range(skip):
            torch.randperm(n, generator=generator)
        perms = [torch.randperm(n, generator=generator) for _ in range(o.critic_iters)]
        if self._worker is None:
            self._worker = CriticWorker(o.critic_r, o.critic_c, o.critic_optimizer, self.regress)
        self._worker.submit(o.critic_r, o.critic_c, o.critic_optimizer,
                            (batch.obs, batch.ret_r, batch.ret_c), perms,
                            o.critic_minibatch(n), o.critic_l2, o.max_grad_norm)
        return skip

    def finish(self, batch: Any, job: int | None, drawn: int) -> dict[str, float]:
        """The critic update after ``drawn`` permutations were drawn since :meth:`start`.

        The helper's result is used when it got the right permutations (then the global
        generator draws them too, as a regression here would have); otherwise the job is
        cancelled and the critics regress here.
        """
        o = self.owner
        if job is not None and self._worker is not None and job == drawn:
            loss_v, loss_vc = self._worker.result(o.critic_r, o.critic_c, o.critic_optimizer)
            n = batch.obs.shape[0]
            for _ in range(o.critic_iters):
                torch.randperm(n)
            stats = {"loss_v": loss_v, "loss_vc": loss_vc}
        else:
            if job is not None and self._worker is not None:
                self._worker.cancel()
            stats = o.update_critics(batch)
        self.choice.record(job is not None, time.perf_counter() - self._start)
        stats["critic_helper"] = float(job is not None and job == drawn)
        return stats

    def stop(self) -> None:
        """Stop the helper."""
        if self._worker is not None:
            self._worker.close()
            self._worker = None
