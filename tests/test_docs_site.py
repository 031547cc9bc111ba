"""The documentation site builds with every warning an error, and the project's LICENSE,
CITATION.cff and CONTRIBUTING.md are there.

``mkdocs build --strict`` fails on a link to a missing page or anchor, a page left out of the
nav, a nav entry without its page and a figure link the hook cannot serve (mkdocs.yml,
``validation:``; docs/hooks/reference_figures.py). MkDocs is part of the ``dev`` extra, so a
missing install fails here rather than skipping.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_site_builds_strict(tmp_path: Path) -> None:
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert (site / "index.html").is_file()
    assert (site / "figures" / "toy" / "fig_2_1.png").is_file()  # served by the hook
    assert not (site / "hooks").exists()


def test_license_citation_contributing() -> None:
    license_text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert license_text.startswith("MIT License")
    assert "Copyright (c) 2026 The semdp authors" in license_text
    assert (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8").startswith("# Contributing")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    for key in ("cff-version", "message", "title", "authors", "type", "license",
                "preferred-citation"):
        assert key in cff, key
    assert cff["cff-version"] == "1.2.0"
    assert cff["title"] == "semdp"
    assert cff["authors"] == [{"name": "The semdp authors"}]
    paper = cff["preferred-citation"]
    assert paper["type"] == "article"
    assert paper["title"] == ("Reinforcement Learning in a Safety-Embedded MDP with "
                              "Trajectory Optimization")
    assert [a["family-names"] for a in paper["authors"]] == [
        "Yang", "Zhou", "Liu", "Zhao", "Held"]
    assert paper["year"] == 2023
    assert "arXiv:2310.06903" in [i["value"] for i in paper["identifiers"]]
    assert "Exploring Safe Reinforcement Learning for Sequential Decision Making" in cff["message"]
