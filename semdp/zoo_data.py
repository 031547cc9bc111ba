"""Where the policy zoo lives: the checkout's ``outputs/reference/``, else the copy inside the
installed package.

The zoo is ``outputs/reference/zoo.yaml`` (an entry name -> a kept run directory, relative to
that folder) and, per entry, the files an evaluation reads. A wheel carries a copy of exactly
those as package data, ``semdp/zoo/`` with the same relative paths: the build step of
``setup.py`` calls :func:`copy_zoo`. So ``semdp-eval zoo:<entry>`` works after
``pip install .`` from any directory, and nothing is downloaded. An editable install and a
checkout read ``outputs/reference/`` itself.

Standard library only: the build step runs this file before any dependency is installed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

#: The files of an entry's run directory that ship: what ``semdp-eval`` reads (the config, the
#: policy, the training's metrics for its labels) and the recorded evaluation.
ENTRY_FILES = ("config.yaml", "policy.pt", "metrics.json", "eval.json")
#: Files an entry cannot be evaluated without.
REQUIRED = ("config.yaml", "policy.pt")
INDEX_NAME = "zoo.yaml"
#: The copy inside an installed package.
PACKAGED = Path(__file__).resolve().parent / "zoo"


def read_index(path: Path) -> dict[str, str]:
    """``zoo.yaml``'s ``name: run directory`` lines (comments and blank lines skipped)."""
    entries: dict[str, str] = {}
    for number, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
        text = line.split(" #")[0].strip()
        if not text or text.startswith("#"):
            continue
        name, sep, value = text.partition(":")
        if not sep or not name.strip() or not value.strip():
            raise ValueError(f"{path}:{number}: expected 'name: run directory', got {line!r}")
        entries[name.strip().strip("'\"")] = value.strip().strip("'\"")
    return entries


def zoo_root(reference: Path) -> Path:
    """The folder holding ``zoo.yaml``: ``reference`` (a checkout's ``outputs/reference``) if
    it has one, else the installed copy."""
    return reference if (reference / INDEX_NAME).is_file() else PACKAGED


def copy_zoo(reference: Path, target: Path) -> list[Path]:
    """Copy ``reference``'s ``zoo.yaml`` and each entry's :data:`ENTRY_FILES` into ``target``
    (same relative paths); return the files written.

    Raises:
        FileNotFoundError: an entry's run directory lacks a :data:`REQUIRED` file.
    """
    reference, target = Path(reference), Path(target)
    written = [target / INDEX_NAME]
    target.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(reference / INDEX_NAME, written[0])
    for name, run_dir in sorted(read_index(reference / INDEX_NAME).items()):
        source = reference / run_dir
        for required in REQUIRED:
            if not (source / required).is_file():
                raise FileNotFoundError(f"zoo entry {name}: {source / required} is missing")
        for file_name in ENTRY_FILES:
            if (source / file_name).is_file():
                destination = target / run_dir / file_name
                destination.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source / file_name, destination)
                written.append(destination)
    return written
