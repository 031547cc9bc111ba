"""Optimiser steps with few kernel launches: Adam on one flat buffer and a lean norm clip.

The networks here are small (64x64), so an optimiser step costs dispatcher calls, not
arithmetic: ``torch.optim.Adam`` runs about ten kernels per parameter tensor and
``clip_grad_norm_`` groups the tensors in Python before its two foreach calls. Both are
elementwise, so running the same operations on one contiguous copy of all parameters gives the
same numbers (each element sees the same arithmetic) with a tenth of the calls:

* :class:`FlatAdam` is ``torch.optim.Adam`` (no weight decay, no AMSGrad) whose step runs on
  one buffer that the parameters are views of; its ``state_dict`` has Adam's layout, so
  checkpoints load into either class;
* :func:`clip_grad_norm` is ``torch.nn.utils.clip_grad_norm_`` (2-norm) without the grouping.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import torch
from torch import nn


def clip_grad_norm(params: Sequence[nn.Parameter], max_norm: float) -> torch.Tensor:
    """Scale the gradients so their joint 2-norm is at most ``max_norm``; return that norm.

    The operations of ``clip_grad_norm_(params, max_norm, foreach=True)`` on one device and
    dtype: per-tensor norms, the norm of their stack, the coefficient
    ``max_norm / (norm + 1e-6)`` clamped at 1, one multiplication of every gradient.
    """
    grads = [p.grad for p in params if p.grad is not None]
    if not grads:
        return torch.tensor(0.0)
    total = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads, 2.0)), 2.0)
    coef = torch.clamp(float(max_norm) / (total + 1e-6), max=1.0)
    torch._foreach_mul_(grads, coef)
    return total


class _OneGroupAdam(torch.optim.Adam):
    """``torch.optim.Adam`` over one parameter group, with ``zero_grad`` dropping the gradients
    of a cached parameter list (the base of :class:`FlatAdam` and :class:`LeanAdam`)."""

    #: Build torch's Adam with its fused CPU kernel.
    fused_kernel: bool | None = None

    def __init__(
        self,
        params: Iterable[nn.Parameter],
        lr: float = 1e-3,
        betas: tuple[float, float] = (0.9, 0.999),
        eps: float = 1e-8,
    ) -> None:
        super().__init__(params, lr=lr, betas=betas, eps=eps, fused=self.fused_kernel)
        if len(self.param_groups) != 1:
            raise ValueError(f"{type(self).__name__} takes one parameter group")
        self._params: list[nn.Parameter] = list(self.param_groups[0]["params"])

    def zero_grad(self, set_to_none: bool = True) -> None:
        """Drop the gradients (``set_to_none=False``: zero them in place)."""
        if not set_to_none:
            super().zero_grad(set_to_none=False)
            return
        for p in self._params:
            p.grad = None


class FlatAdam(_OneGroupAdam):
    """``torch.optim.Adam`` on one contiguous buffer (one parameter group, every parameter with
    a gradient at every step).

    The parameters become views of the buffer (``param.data`` is re-pointed; modules and
    ``load_state_dict`` keep working in place); a parameter pointed elsewhere afterwards is
    copied back in before the next step.

    Args:
        params: the parameters.
        lr, betas, eps: as ``torch.optim.Adam``.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:  # _OneGroupAdam's arguments
        super().__init__(*args, **kwargs)
        self._sizes = [p.numel() for p in self._params]
        first = self._params[0]
        self._flat = torch.zeros(sum(self._sizes), dtype=first.dtype, device=first.device)
        self._exp_avg = torch.zeros_like(self._flat)
        self._exp_avg_sq = torch.zeros_like(self._flat)
        self._steps = 0
        self._views: list[torch.Tensor] = []
        self._attach()

    def _slices(self, flat: torch.Tensor) -> list[torch.Tensor]:
        return [v.view_as(p) for v, p in
                zip(flat.split(self._sizes), self._params, strict=True)]

    def _attach(self) -> None:
        """Copy the parameters' values into the buffer and make them views of it."""
        views = self._slices(self._flat)
        with torch.no_grad():
            for view, p in zip(views, self._params, strict=True):
                view.copy_(p)
                p.data = view
        self._views = views

    @torch.no_grad()
    def step(self, closure: Any = None) -> None:  # type: ignore[override]
        """One Adam step (``_single_tensor_adam``'s arithmetic) on the flat buffer."""
        if closure is not None:
            raise ValueError("FlatAdam.step takes no closure")
        flat, exp_avg, exp_avg_sq = self.buffers()
        grads = [p.grad for p in self._params]
        if any(g is None for g in grads):
            raise RuntimeError("FlatAdam needs a gradient for every parameter")
        grad = torch.cat([g.reshape(-1) for g in grads])
        self.step_buffers(flat, grad, exp_avg, exp_avg_sq)

    def buffers(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The flat parameters, ``exp_avg`` and ``exp_avg_sq`` (parameter order, in place)."""
        if any(p.data_ptr() != v.data_ptr() for p, v in zip(self._params, self._views,
                                                           strict=True)):
            self._attach()
        return self._flat, self._exp_avg, self._exp_avg_sq

    @torch.no_grad()
    def step_buffers(
        self,
        params: torch.Tensor,
        grad: torch.Tensor,
        exp_avg: torch.Tensor,
        exp_avg_sq: torch.Tensor,
    ) -> None:
        """One Adam step (``_single_tensor_adam``'s arithmetic) on flat buffers given in any
        order of the elements (the arithmetic is elementwise), counted as a step of this
        optimiser; :meth:`step` runs it on :meth:`buffers`."""
        group = self.param_groups[0]
        lr, (beta1, beta2), eps = group["lr"], group["betas"], group["eps"]
        self._steps += 1
        exp_avg.lerp_(grad, 1 - beta1)
        exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
        step = float(self._steps)
        bias_correction1 = 1 - beta1**step
        bias_correction2 = 1 - beta2**step
        step_size = lr / bias_correction1
        bias_correction2_sqrt = bias_correction2**0.5
        denom = (exp_avg_sq.sqrt() / bias_correction2_sqrt).add_(eps)
        params.addcdiv_(exp_avg, denom, value=-step_size)

    def state_dict(self) -> dict[str, Any]:
        """``torch.optim.Adam``'s layout: per-parameter ``step``, ``exp_avg``, ``exp_avg_sq``."""
        group = {k: v for k, v in self.param_groups[0].items() if k != "params"}
        group["params"] = list(range(len(self._params)))
        state: dict[int, dict[str, torch.Tensor]] = {}
        if self._steps:
            for i, (m, v) in enumerate(zip(self._slices(self._exp_avg),
                                           self._slices(self._exp_avg_sq), strict=True)):
                state[i] = {"step": torch.tensor(float(self._steps)), "exp_avg": m.clone(),
                            "exp_avg_sq": v.clone()}
        return {"state": state, "param_groups": [group]}

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict` of this class or of ``torch.optim.Adam``."""
        super().load_state_dict(state_dict)
        states = [self.state.get(p, {}) for p in self._params]
        steps = {float(s["step"]) for s in states if s}
        if len(steps) > 1 or (steps and not all(states)):
            raise ValueError("FlatAdam needs the same step count for every parameter")
        self._steps = int(steps.pop()) if steps else 0
        with torch.no_grad():
            for dest, key in ((self._exp_avg, "exp_avg"), (self._exp_avg_sq, "exp_avg_sq")):
                dest.zero_()
                if self._steps:
                    for view, s in zip(self._slices(dest), states, strict=True):
                        view.copy_(s[key])
        self.state.clear()


class LeanAdam(_OneGroupAdam):
    """``torch.optim.Adam(fused=True)`` (no weight decay, no AMSGrad) whose step calls the fused
    CPU kernel directly, without the optimiser's per-step grouping and checks.

    For networks big enough that the arithmetic is the kernel's (SAC's 256x256 critics), the
    ~0.15 ms of Python around each ``Adam.step`` is what remains to save: this step is the
    same two operations as torch's ``_fused_adam`` on one device and dtype (the step counters
    incremented, then ``torch._fused_adam_``), so the numbers are Adam(fused=True)'s bit for
    bit, and ``state_dict``/``load_state_dict`` are Adam's.

    Args:
        params: the parameters (one group; all on the CPU in one dtype).
        lr, betas, eps: as ``torch.optim.Adam``.
    """

    fused_kernel = True
    #: Adam's state tensors (``exp_avg``, ``exp_avg_sq``, ``step`` lists) once created.
    _state_lists: tuple[list[torch.Tensor], ...] | None = None

    @torch.no_grad()
    def step(self, closure: Any = None) -> None:  # type: ignore[override]
        """One fused Adam step (the first one through ``torch.optim.Adam``, which creates the
        state; later ones on the cached state tensors)."""
        if closure is not None:
            raise ValueError("LeanAdam.step takes no closure")
        if self._state_lists is None:
            super().step()
            states = [self.state[p] for p in self._params]
            self._state_lists = tuple([s[key] for s in states]
                                      for key in ("exp_avg", "exp_avg_sq", "step"))
            return
        grads = [p.grad for p in self._params]
        if any(g is None for g in grads):
            raise RuntimeError("LeanAdam needs a gradient for every parameter")
        self._fused_step(grads)

    def apply_gradients(self, grads: Sequence[torch.Tensor]) -> None:
        """:meth:`step` with the gradients given in parameter order instead of read from
        ``.grad``, and without the optimiser's step hooks (for callers that run under
        ``torch.no_grad`` and compute the gradients themselves, e.g. the SAC learner's
        ``gradients="written"`` kernel): the same arithmetic."""
        if self._state_lists is None:
            for p, g in zip(self._params, grads, strict=True):
                p.grad = g
            self.step()
            for p in self._params:
                p.grad = None
            return
        if len(grads) != len(self._params):
            raise ValueError(f"{len(self._params)} gradients expected, got {len(grads)}")
        self._fused_step(list(grads))

    def _fused_step(self, grads: list[torch.Tensor]) -> None:
        """The two operations of ``torch.optim.Adam(fused=True)``'s step on the cached state."""
        assert self._state_lists is not None
        exp_avgs, exp_avg_sqs, steps = self._state_lists
        group = self.param_groups[0]
        beta1, beta2 = group["betas"]
        torch._foreach_add_(steps, 1)
        torch._fused_adam_(
            self._params, grads, exp_avgs, exp_avg_sqs, [], steps,
            amsgrad=False, lr=group["lr"], beta1=beta1, beta2=beta2, weight_decay=0.0,
            eps=group["eps"], maximize=False, grad_scale=None, found_inf=None,
        )

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """Restore a ``torch.optim.Adam`` state dict (the cached state is rebuilt)."""
        super().load_state_dict(state_dict)
        self._state_lists = None
        if all(p in self.state and "exp_avg" in self.state[p] for p in self._params):
            states = [self.state[p] for p in self._params]
            self._state_lists = tuple([s[key] for s in states]
                                      for key in ("exp_avg", "exp_avg_sq", "step"))
