"""FlatAdam and the lean norm clip give torch's numbers bit for bit, and their state dicts are
interchangeable with torch.optim.Adam's (checkpoints load into either)."""

from __future__ import annotations

import copy

import torch
from torch import nn

from semdp.common.networks import GaussianActor, ValueCritic
from semdp.common.optim import FlatAdam, LeanAdam, clip_grad_norm


def _train(net: nn.Module, opt: torch.optim.Optimizer, steps: int, seed: int,
           lean_clip: bool) -> None:
    gen = torch.Generator().manual_seed(seed)
    for k in range(steps):
        x = torch.randn(32, 6, generator=gen) * 3
        loss = (net(x) ** 2).mean() if isinstance(net, ValueCritic) else \
            net.log_prob(x, torch.randn(32, 2, generator=gen)).mean()
        opt.zero_grad()
        loss.backward()
        params = list(net.parameters())
        if lean_clip:
            clip_grad_norm(params, 0.5)
        else:
            torch.nn.utils.clip_grad_norm_(params, 0.5)
        for group in opt.param_groups:
            group["lr"] = 1e-2 * (1 - k / (2 * steps))  # a decaying rate, as PPO's actor
        opt.step()


def _same(a: nn.Module, b: nn.Module) -> bool:
    return all(torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters(), strict=True))


def test_flat_adam_and_lean_clip_match_torch_bit_for_bit() -> None:
    torch.manual_seed(0)
    for net in (ValueCritic(6, (16, 16)), GaussianActor(6, 2, (16, 16))):
        ref, flat = copy.deepcopy(net), copy.deepcopy(net)
        _train(ref, torch.optim.Adam(ref.parameters(), lr=1e-2), 150, 1, lean_clip=False)
        _train(flat, FlatAdam(flat.parameters(), lr=1e-2), 150, 1, lean_clip=True)
        assert _same(ref, flat)


def test_flat_adam_state_dicts_interchange_with_torch_adam() -> None:
    torch.manual_seed(1)
    net = ValueCritic(6, (8, 8))
    a, b = copy.deepcopy(net), copy.deepcopy(net)
    opt_a, opt_b = torch.optim.Adam(a.parameters(), lr=1e-2), FlatAdam(b.parameters(), lr=1e-2)
    assert opt_b.state_dict()["state"] == {}
    _train(a, opt_a, 20, 2, lean_clip=False)
    _train(b, opt_b, 20, 2, lean_clip=True)
    saved_torch, saved_flat = opt_a.state_dict(), opt_b.state_dict()
    assert saved_flat["param_groups"] == saved_torch["param_groups"]
    for i, state in saved_torch["state"].items():
        for key, value in state.items():
            assert torch.equal(saved_flat["state"][i][key], value)
    # torch -> flat and flat -> torch, then both continue identically
    c, d = copy.deepcopy(a), copy.deepcopy(b)
    opt_c = FlatAdam(c.parameters(), lr=1e-2)
    opt_c.load_state_dict(saved_torch)
    opt_d = torch.optim.Adam(d.parameters(), lr=1e-2)
    opt_d.load_state_dict(saved_flat)
    _train(a, opt_a, 10, 3, lean_clip=False)
    _train(c, opt_c, 10, 3, lean_clip=True)
    _train(d, opt_d, 10, 3, lean_clip=False)
    assert _same(a, c) and _same(a, d)


def test_flat_adam_follows_parameters_loaded_or_repointed_from_outside() -> None:
    torch.manual_seed(2)
    net, ref = ValueCritic(6, (8, 8)), ValueCritic(6, (8, 8))
    opt, opt_ref = FlatAdam(net.parameters(), lr=1e-2), torch.optim.Adam(ref.parameters(), 1e-2)
    net.load_state_dict(ref.state_dict())  # copies into the flat buffer's views
    first = next(net.parameters())
    first.data = first.data.clone()  # re-pointed: copied back in at the next step
    _train(net, opt, 5, 4, lean_clip=True)
    _train(ref, opt_ref, 5, 4, lean_clip=False)
    assert _same(net, ref)


def test_lean_adam_is_fused_torch_adam_bit_for_bit_and_resumes_from_its_state() -> None:
    torch.manual_seed(3)
    net = GaussianActor(6, 2, (16, 16))
    ref, lean = copy.deepcopy(net), copy.deepcopy(net)
    opt_ref = torch.optim.Adam(ref.parameters(), lr=1e-2, fused=True)
    opt_lean = LeanAdam(lean.parameters(), lr=1e-2)
    _train(ref, opt_ref, 40, 5, lean_clip=False)
    _train(lean, opt_lean, 40, 5, lean_clip=False)
    assert _same(ref, lean)
    saved = opt_lean.state_dict()
    for i, state in opt_ref.state_dict()["state"].items():
        assert all(torch.equal(saved["state"][i][k], v) for k, v in state.items())
    # a checkpoint round trip (a fresh LeanAdam loads torch's state) continues identically,
    # and a learning-rate change (as a schedule) reaches the fused kernel
    again = copy.deepcopy(ref)
    opt_again = LeanAdam(again.parameters(), lr=1e-2)
    opt_again.load_state_dict(copy.deepcopy(opt_ref.state_dict()))  # as saved and loaded
    _train(ref, opt_ref, 10, 6, lean_clip=False)
    _train(again, opt_again, 10, 6, lean_clip=False)
    assert _same(ref, again)
