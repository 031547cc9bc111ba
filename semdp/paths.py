"""Locations shared by the Hydra apps.

The Hydra configs live in the repository's top-level ``conf/``; the package reaches them as
``semdp/conf`` (a link to ``../conf`` in a checkout, a copy inside an installed wheel), so the
apps find their configs whether the project is installed editable or as a package.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
#: Hydra config directory.
CONF_DIR = PACKAGE_DIR / "conf"
#: The checkout the package runs from; for an installed package, the working directory (where
#: the apps write ``outputs/``).
REPO_ROOT = PACKAGE_DIR.parent if (PACKAGE_DIR.parent / "pyproject.toml").is_file() else Path.cwd()
#: Committed, curated results produced by the project's own commands (in a checkout).
REFERENCE_DIR = REPO_ROOT / "outputs" / "reference"

if not (CONF_DIR / "train.yaml").is_file():  # pragma: no cover - a broken install
    raise RuntimeError(f"Hydra config directory not found at {CONF_DIR}: reinstall the package")
