"""Fisher-vector products of the Gaussian actor, written out (TRPO's and CPO's inner loop).

TRPO and CPO solve ``(F + damping I) x = g`` by conjugate gradients, with ``F`` the Hessian of
the mean ``KL(pi_old || pi_theta)`` at ``theta = theta_old`` (docs/training.md, "Algorithms
and recorded choices"); autograd gives ``F v`` by differentiating ``grad KL . v`` a second
time. For
the diagonal Gaussian with a state-independent ``log_std`` that Hessian is known in closed form
at ``theta_old``, where the means and standard deviations agree:

    F v = (1/N) J_mu^T diag(1/sigma^2) J_mu v_mu  (+)  2 v_log_std,

``J_mu`` the Jacobian of the mean network's outputs over the batch; the cross terms and the
terms with second derivatives of ``mu`` vanish there. ``J_mu v`` is one forward pass of
tangents through the MLP and ``J_mu^T u`` one backward pass, both written out with matrix
products (:mod:`semdp.algos.kernels.mlp_grads`), so a product costs the arithmetic of three passes
without autograd's double-backward graph. The activations are computed once per update.

The product is defined by :meth:`semdp.algos.trpo.TRPO.kl_hessian_product` (double backward of
``TRPO.mean_kl``); this kernel is the presets' opt-in (``gradients="written"``) and is checked
against it when TRPO or CPO is built
(:meth:`~semdp.algos.kernels.written.WrittenDerivatives.check_fisher`, to ``RTOL`` = 1e-4; they
agree to ~1e-7). Not timed against ``torch.compile`` here.
"""

from __future__ import annotations

import torch
from torch import nn

from semdp.algos.kernels.mlp_grads import (
    ACTIVATION_GRADS,
    ACTIVATIONS,
    backprop_mlp,
    gaussian_actor_layers,
)


class GaussianFisher:
    """``v -> (F + damping I) v`` at the actor's current parameters for a batch of observations.

    Use :meth:`build`, which returns ``None`` for actors it does not cover (the autograd
    product applies there). ``v`` is laid out as ``torch.nn.utils.parameters_to_vector`` of
    ``actor.parameters()`` (``log_std``, then the mean network's layers).
    """

    def __init__(
        self,
        layers: list[tuple[torch.Tensor, torch.Tensor]],
        inputs: list[torch.Tensor],
        slopes: list[torch.Tensor],
        inv_var: torch.Tensor,
        damping: float,
    ) -> None:
        self.layers, self.inputs, self.slopes = layers, inputs, slopes
        self.inv_var, self.damping = inv_var, damping

    @classmethod
    @torch.no_grad()
    def build(cls, actor: nn.Module, obs: torch.Tensor, damping: float) -> GaussianFisher | None:
        """The product for ``actor`` (a ``log_std`` vector and a ``mean_net`` MLP, in that
        parameter order) on ``obs``; ``None`` if the actor is not of that form."""
        parts = gaussian_actor_layers(actor)
        if parts is None:
            return None
        linears, activations = parts
        log_std: torch.Tensor = actor.log_std
        layers = [(m.weight.detach(), m.bias.detach()) for m in linears]
        inputs, slopes = [obs], []
        h = obs
        for (w, b), act in zip(layers[:-1], activations, strict=True):
            h = ACTIVATIONS[act](torch.addmm(b, h, w.t()))
            inputs.append(h)
            slopes.append(ACTIVATION_GRADS[act](h))
        inv_var = torch.exp(-2.0 * log_std.detach()) / obs.shape[0]
        return cls(layers, inputs, slopes, inv_var, float(damping))

    @torch.no_grad()
    def __call__(self, v: torch.Tensor) -> torch.Tensor:
        """``(F + damping I) v``."""
        out = torch.empty_like(v)
        n_std = self.inv_var.numel()
        torch.mul(v[:n_std], 2.0, out=out[:n_std])  # d^2 KL / d log_std^2 = 2 per dimension
        views, start = [], n_std
        for w, b in self.layers:  # (weight, bias) slices of v and of out
            n_w, n_b = w.numel(), b.numel()
            views.append((v[start:start + n_w].view_as(w), v[start + n_w:start + n_w + n_b],
                          out[start:start + n_w].view_as(w), out[start + n_w:start + n_w + n_b]))
            start += n_w + n_b
        # tangent of the mean: J_mu v, layer by layer
        tangent: torch.Tensor | None = None
        last = len(self.layers) - 1
        for k, ((w, _), (dw, db, _, _)) in enumerate(zip(self.layers, views, strict=True)):
            z = torch.addmm(db, self.inputs[k], dw.t())
            if tangent is not None:
                z.addmm_(tangent, w.t())
            tangent = z * self.slopes[k] if k < last else z
        assert tangent is not None
        # back through the network with diag(1/sigma^2)/N applied
        backprop_mlp(tangent * self.inv_var, self.inputs, [w for w, _ in self.layers],
                     self.slopes, [(gw, gb) for _, _, gw, gb in views])
        return out.add_(v, alpha=self.damping)
