"""The policy zoo: trained policies kept in the repository, evaluated by name.

``outputs/reference/zoo.yaml`` maps a name to a kept run directory (relative to
``outputs/reference``) that holds ``config.yaml`` and ``policy.pt``; ``semdp-eval zoo:<name>``
evaluates it as ``semdp-eval <run dir>`` would, writing its results under
``outputs/eval/<name>/`` (of the working directory, outside a checkout) instead of into the
committed folder. Outside a checkout the index and the run directories are the copy the package
ships (:mod:`semdp.zoo_data`).
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import OmegaConf

from semdp.evaluation.errors import EvalError
from semdp.paths import REFERENCE_DIR, REPO_ROOT
from semdp.zoo_data import INDEX_NAME, zoo_root

#: Prefix of a zoo entry on the ``semdp-eval`` command line.
PREFIX = "zoo:"
#: The checkout's ``outputs/reference/zoo.yaml``, else the installed package's copy.
INDEX = zoo_root(REFERENCE_DIR) / INDEX_NAME


def entries(index: Path | None = None) -> dict[str, Path]:
    """Every entry of ``index`` (default :data:`INDEX`): name -> run directory."""
    index = INDEX if index is None else index
    if not index.is_file():
        return {}
    table = OmegaConf.to_container(OmegaConf.load(index))
    if not isinstance(table, dict):
        raise EvalError(f"{index} must map names to run directories")
    return {str(name): index.parent / str(path) for name, path in table.items()}


def resolve(argument: str, index: Path | None = None) -> tuple[Path, Path | None]:
    """``(run dir, output root)`` of a ``semdp-eval`` target: a run directory (output root
    ``None``: beside the run) or ``zoo:<name>`` (output root ``outputs/eval/<name>``).

    Raises:
        EvalError: an unknown zoo name (the message lists the known ones).
    """
    if not argument.startswith(PREFIX):
        return Path(argument), None
    name = argument[len(PREFIX):]
    index = INDEX if index is None else index
    known = entries(index)
    if name not in known:
        raise EvalError(f"no zoo entry {name!r}; known: {', '.join(sorted(known)) or 'none'} "
                        f"({index})")
    return known[name], REPO_ROOT / "outputs" / "eval" / name
