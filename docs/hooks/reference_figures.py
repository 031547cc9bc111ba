"""MkDocs hook: serve committed result figures without copying them into ``docs/``.

A page shows a figure of ``outputs/reference/`` by linking ``figures/<path below
outputs/reference>`` (e.g. ``![Fig. 2.1](figures/toy/fig_2_1.png)``). Before the build, this hook
finds every such link in the pages and adds the committed file to the site under that name, so
``mkdocs build --strict`` checks the link like any other. A link to a figure that is not
committed stops the build with its name.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

#: The committed results the figures come from.
REFERENCE = Path(__file__).resolve().parents[2] / "outputs" / "reference"
#: A Markdown image or link whose target is ``figures/...`` (from any page depth).
FIGURE_LINK = re.compile(r"\]\((?:\.\./)*figures/([^)\s]+\.(?:png|gif|svg|jpg))\)")


def figures_named(markdown: str) -> set[str]:
    """Paths below ``outputs/reference`` of the figures a page links."""
    return set(FIGURE_LINK.findall(markdown))


def on_files(files: Files, config) -> Files:
    """Add each linked reference figure to the site as ``figures/<path>``."""
    wanted: set[str] = set()
    for page in files.documentation_pages():
        wanted |= figures_named(Path(page.abs_src_path).read_text(encoding="utf-8"))
    for name in sorted(wanted):
        source = REFERENCE / name
        if not source.is_file():
            raise PluginError(f"reference_figures: a page shows figures/{name}, but "
                              f"outputs/reference/{name} is not committed")
        files.append(File.generated(config, f"figures/{name}", abs_src_path=str(source)))
    return files
