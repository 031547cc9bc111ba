"""Policy files are data: ``policy.pt`` and follower weights load without running code.

A ``torch.save`` file is a pickle, and unpickling may call any function the file names. The
policy files this project writes and shares (``policy.pt`` of every run and zoo entry, the
followers' weights) hold tensors, numbers, strings and containers only, so they are read with
``torch.load(..., weights_only=True)``, whose unpickler accepts those and refuses every other
global, plus the globals a numeric NumPy array needs (:data:`ALLOWED_GLOBALS`: observation
normalisers keep their statistics as arrays; an array's elements are unpickled by the same
restricted unpickler). A file that needs more is refused with one line naming it, and so is a
file that is empty, truncated or not a torch file at all.

Checkpoints (``checkpoints/last.pt``) are different: they pickle whole environments so that a
resume continues bit for bit, and are trusted as the output of your own runs only
(``resume=`` and the tools that read them say so).
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import torch

#: The globals a policy file may name beyond torch's tensors and plain values: a NumPy array's
#: reconstruction and its numeric dtypes.
ALLOWED_GLOBALS = (np._core.multiarray._reconstruct, np.ndarray, np.dtype,
                   *(type(np.dtype(code)) for code in ("f4", "f8", "i4", "i8", "u1", "?")))


class PolicyFileError(ValueError):
    """A policy or weight file that cannot be loaded as data; the message is one line."""


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


def load_data(path: str | Path, what: str) -> dict[str, Any]:
    """The mapping saved in ``path`` (a ``what``: "policy", "follower weights"), read without
    running any code the file may carry.

    Raises:
        PolicyFileError: no such file, an empty, truncated or foreign file, a file holding
            objects other than tensors and plain values (refused, never unpickled), or a file
            that does not hold a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(f"{path}: no such {what} file")
    if path.stat().st_size == 0:
        raise PolicyFileError(f"{path}: empty file, not a {what}")
    try:
        with torch.serialization.safe_globals(list(ALLOWED_GLOBALS)):
            payload = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        detail = next((line.strip() for line in str(exc).splitlines()
                       if "Unsupported global" in line), _first_line(exc))
        raise PolicyFileError(
            f"{path}: refused: the {what} holds more than tensors and plain values, and "
            f"loading it could run code ({detail})") from None
    except Exception as exc:  # whatever a damaged file makes the reader raise
        raise PolicyFileError(f"{path}: cannot read the {what} (truncated or not a torch "
                              f"file: {_first_line(exc)})") from None
    if not isinstance(payload, dict):
        raise PolicyFileError(f"{path}: a {what} file holds a mapping, this one a "
                              f"{type(payload).__name__}")
    return payload
