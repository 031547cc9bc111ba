"""Locations shared by the Hydra apps."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
#: Hydra config directory (the repository's top-level ``conf/``; the package is installed editable).
CONF_DIR = REPO_ROOT / "conf"
#: Committed, curated results produced by the project's own commands.
REFERENCE_DIR = REPO_ROOT / "outputs" / "reference"

if not CONF_DIR.is_dir():  # pragma: no cover - only hit by a non-editable install
    raise RuntimeError(
        f"Hydra config directory not found at {CONF_DIR}. Install the project in editable mode "
        "from a checkout: pip install -e ."
    )
