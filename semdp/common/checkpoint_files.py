"""Checkpoints are trusted as your own runs only: each one is signed by the account that wrote it.

A checkpoint (``checkpoints/last.pt``) pickles whole environments so that a resume continues bit
for bit; unpickling it may run any code the file names. So the run that writes one also writes
``last.pt.sig``: an HMAC-SHA256 of the file's bytes under a key private to this account
(``~/.config/semdp/checkpoint.key``, created on first use with mode 0600; the environment variable
``SEMDP_CHECKPOINT_KEY`` names another key file). Before unpickling, the signature is checked: a
checkpoint that was replaced, or that comes from another account or machine, is refused with one
line. A checkpoint you do trust (your own, moved from another machine) is read after
``SEMDP_TRUST_CHECKPOINTS=1``, which skips the check. Shared policies travel as ``policy.pt``,
which is data (:mod:`semdp.common.policy_files`).
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
from pathlib import Path
from typing import Any

import torch

from semdp import legacy

SIGNATURE_SUFFIX = ".sig"
KEY_ENV = "SEMDP_CHECKPOINT_KEY"
TRUST_ENV = "SEMDP_TRUST_CHECKPOINTS"


class CheckpointError(ValueError):
    """A checkpoint that is not to be unpickled; the message is one line."""


def key_path() -> Path:
    """The key file: ``$SEMDP_CHECKPOINT_KEY``, else ``~/.config/semdp/checkpoint.key``."""
    named = os.environ.get(KEY_ENV)
    if named:
        return Path(named).expanduser()
    config = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    return config / "semdp" / "checkpoint.key"


def _key() -> bytes:
    path = key_path()
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        try:  # O_EXCL: two runs starting together agree on one key
            handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            pass
        else:
            with os.fdopen(handle, "wb") as out:
                out.write(secrets.token_bytes(32))
    key = path.read_bytes()
    if len(key) < 16:
        raise CheckpointError(f"{path}: checkpoint key too short ({len(key)} bytes)")
    return key


def _signature(path: Path) -> str:
    mac = hmac.new(_key(), digestmod=hashlib.sha256)
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            mac.update(block)
    return mac.hexdigest()


def signature_path(path: Path) -> Path:
    """Where the signature of checkpoint ``path`` is kept (``last.pt.sig``)."""
    return path.with_name(path.name + SIGNATURE_SUFFIX)


def save_checkpoint_file(payload: dict[str, Any], path: str | Path) -> None:
    """``torch.save`` of ``payload`` to ``path`` with its signature, both replaced atomically
    (a crash leaves the previous pair or the new one, and a mismatch is refused on load)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    torch.save(payload, tmp)
    sig_tmp = signature_path(tmp)
    sig_tmp.write_text(_signature(tmp) + "\n")
    tmp.replace(path)
    sig_tmp.replace(signature_path(path))


def check_checkpoint_file(path: str | Path) -> None:
    """Raise :class:`CheckpointError` unless ``path`` carries this account's signature (or
    ``SEMDP_TRUST_CHECKPOINTS=1`` is set)."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint")
    if os.environ.get(TRUST_ENV) == "1":
        return
    how = (f"checkpoints run code when loaded, so only this account's own are read; if you "
           f"trust it, set {TRUST_ENV}=1")
    sig = signature_path(path)
    if not sig.is_file():
        raise CheckpointError(f"{path}: refused: no signature ({sig.name}): {how}")
    if not hmac.compare_digest(sig.read_text().strip(), _signature(path)):
        raise CheckpointError(f"{path}: refused: not signed by this account, or changed since "
                              f"it was written: {how}")


def load_checkpoint_file(path: str | Path, map_location: str | None = None) -> dict[str, Any]:
    """The payload of a checkpoint written by :func:`save_checkpoint_file`, after
    :func:`check_checkpoint_file` (the whole pickle is then loaded: environments included)."""
    check_checkpoint_file(path)
    # the unpickler of semdp.legacy: objects pickled by earlier versions come back in today's form
    payload = torch.load(path, map_location=map_location, weights_only=False,
                         pickle_module=legacy)
    if not isinstance(payload, dict):
        raise CheckpointError(f"{path}: a checkpoint holds a mapping, this one a "
                              f"{type(payload).__name__}")
    return payload
