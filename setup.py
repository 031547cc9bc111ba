"""The build step that ships the policy zoo inside the package (the rest of the build is
``pyproject.toml``'s).

A wheel (``pip install .``, ``pip wheel .``) gets ``semdp/zoo/``: ``outputs/reference/zoo.yaml``
and, per entry, the run directory's config, policy, metrics and recorded evaluation
(:func:`semdp.zoo_data.copy_zoo`), so ``semdp-eval zoo:<entry>`` works from any directory. An
editable install reads the checkout's ``outputs/reference/`` instead and copies nothing.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
# semdp/zoo_data.py by its path: importing the package would need its dependencies.
_spec = importlib.util.spec_from_file_location("_semdp_zoo_data", ROOT / "semdp" / "zoo_data.py")
zoo_data = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(zoo_data)


class BuildPyWithZoo(build_py):
    """``build_py``, then the zoo into ``<build>/semdp/zoo``."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        reference = ROOT / "outputs" / "reference"
        if not (reference / zoo_data.INDEX_NAME).is_file():
            self.warn("outputs/reference/zoo.yaml not found: the package ships without the zoo")
            return
        written = zoo_data.copy_zoo(reference, Path(self.build_lib) / "semdp" / "zoo")
        self.announce(f"copied the policy zoo: {len(written)} files", level=2)


setup(cmdclass={"build_py": BuildPyWithZoo})
