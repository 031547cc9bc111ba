"""Locations shared by the Hydra apps.

The Hydra configs live in the repository's top-level ``conf/``; the package reaches them as
``semdp/conf`` (a link to ``../conf`` in a checkout, a copy inside an installed wheel), so the
apps find their configs whether the project is installed editable or as a package. Importing
this module also registers the ``env`` options that are robot x task products
(:mod:`semdp.env_products`: ``env=point_goal1``, ``env=semdp_car_push1``, ...), so whatever
composes from :data:`CONF_DIR` sees them.
"""

from __future__ import annotations

from pathlib import Path

from semdp import env_products

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

env_products.register()
