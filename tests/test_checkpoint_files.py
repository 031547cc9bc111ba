"""Checkpoints are trusted as this account's own runs only (semdp/common/checkpoint_files.py): a
checkpoint that was replaced, unsigned or signed with another key is refused before it is
unpickled (a planted ``__reduce__`` never runs), by the loader, ``semdp-train resume=`` and
``semdp-eval``; a signed one loads; ``SEMDP_TRUST_CHECKPOINTS=1`` reads one you trust."""

from __future__ import annotations

import shutil
import stat
from collections.abc import Callable
from pathlib import Path

import pytest
import torch
from omegaconf import DictConfig

from semdp.algos.base import CHECKPOINT_NAME
from semdp.cli.train import run
from semdp.common.checkpoint_files import (
    CheckpointError,
    key_path,
    load_checkpoint_file,
    save_checkpoint_file,
    signature_path,
)
from semdp.evaluation.errors import EvalError
from semdp.evaluation.run import evaluate_run


class _Planted:
    """Unpickling this calls ``open(marker, "w")``: it creates the marker file."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (str(self.marker), "w"))


def _sign_elsewhere(payload: object, path: Path, tmp_path: Path,
                    monkeypatch: pytest.MonkeyPatch) -> None:
    """``payload`` saved and signed under another account's key."""
    with monkeypatch.context() as other:
        other.setenv("SEMDP_CHECKPOINT_KEY", str(tmp_path / "other.key"))
        save_checkpoint_file(payload, path)  # type: ignore[arg-type]


def test_a_signed_checkpoint_loads_and_the_key_is_private(tmp_path: Path) -> None:
    path = tmp_path / "last.pt"
    save_checkpoint_file({"algo": {"w": torch.arange(3)}}, path)
    assert signature_path(path).is_file() and not list(tmp_path.glob("*.tmp*"))
    assert torch.equal(load_checkpoint_file(path)["algo"]["w"], torch.arange(3))
    assert stat.S_IMODE(key_path().stat().st_mode) == 0o600


def test_replaced_unsigned_and_foreign_checkpoints_are_refused_and_run_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    marker = tmp_path / "pwned"
    path = tmp_path / "last.pt"
    save_checkpoint_file({"algo": {}}, path)
    torch.save({"algo": {"x": _Planted(marker)}}, path)  # replaced after signing
    with pytest.raises(CheckpointError, match="changed since it was written"):
        load_checkpoint_file(path)
    signature_path(path).unlink()  # unsigned
    with pytest.raises(CheckpointError, match="no signature"):
        load_checkpoint_file(path)
    _sign_elsewhere({"algo": {"x": _Planted(marker)}}, path, tmp_path, monkeypatch)
    with pytest.raises(CheckpointError, match="not signed by this account") as info:
        load_checkpoint_file(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
    assert not marker.exists()
    monkeypatch.setenv("SEMDP_TRUST_CHECKPOINTS", "1")  # the user vouches for it: it loads
    load_checkpoint_file(path)
    assert marker.exists()


@pytest.fixture
def finished_run(tiny_train: Callable[..., DictConfig], tmp_path: Path) -> Path:
    run_dir = tmp_path / "run"
    run(tiny_train("ppo_lag"), run_dir)
    return run_dir


def test_resume_and_eval_refuse_a_foreign_checkpoint(
        finished_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        tiny_train: Callable[..., DictConfig]) -> None:
    marker = tmp_path / "pwned"
    copy = tmp_path / "copy"
    shutil.copytree(finished_run, copy)
    ckpt = copy / "checkpoints" / CHECKPOINT_NAME
    payload = torch.load(ckpt, weights_only=False)
    payload["algo"]["planted"] = _Planted(marker)
    _sign_elsewhere(payload, ckpt, tmp_path, monkeypatch)
    cfg = tiny_train("ppo_lag", f"resume={copy}")
    with pytest.raises(ValueError, match=r"resume=.*not signed by this account"):
        run(cfg, tmp_path / "out")
    (copy / "policy.pt").unlink()  # semdp-eval then reads the checkpoint
    with pytest.raises(EvalError, match="not signed by this account"):
        evaluate_run(copy, ["episodes=1"])
    assert not marker.exists() and not list(copy.glob("eval_*"))


def test_a_run_resumes_from_its_own_signed_checkpoint(
        finished_run: Path, tmp_path: Path, tiny_train: Callable[..., DictConfig]) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(finished_run, copy)
    (copy / "metrics.json").unlink()
    metrics = run(tiny_train("ppo_lag", f"resume={copy}"), tmp_path / "out")
    assert metrics["status"] == "completed"
