"""Package boundaries: solvers and sims are torch-free, Hydra-free libraries; no import cycles;
and semdp's packages in layers, each importing only from its own layer or lower ones:

0. libraries: ``solvers``, ``sims``;
1. common: ``semdp.common`` and the top-level modules every layer uses: the package itself
   (``semdp/__init__.py``), ``numerics``, ``paths``, ``env_products``, ``configs`` (composing
   ``conf/``), ``run_config`` (loading a run's saved config), ``legacy`` (the files of earlier
   versions, read on loading), ``envs`` (the env factory) and ``zoo_data`` (where the policy zoo
   lives: the checkout or the installed package);
2. methods: ``semdp.algos`` (the algorithms) and ``semdp.embedded`` (the Safety-Embedded MDP at
   run time, thesis Alg. 2);
3. runs: ``semdp.build`` (a training run's objects), ``semdp.evaluation`` (loading and
   measuring runs), ``semdp.reporting`` and ``semdp.experiments`` (tables, figures, a run's
   artefacts), ``semdp.rendering`` (evaluation videos), ``semdp.benchmarks``;
4. apps: ``semdp.cli``.

Imports under ``if TYPE_CHECKING:`` do not run and do not count.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "solvers": {"torch", "hydra", "omegaconf", "sims", "semdp", "pymunk", "gymnasium"},
    "sims": {"torch", "hydra", "omegaconf", "solvers", "semdp", "casadi", "osqp"},
}


def _imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    roots: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_library_does_not_import_forbidden_packages(package: str) -> None:
    offenders = {
        str(path.relative_to(ROOT)): sorted(_imported_roots(path) & FORBIDDEN[package])
        for path in (ROOT / package).rglob("*.py")
    }
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"{package}/ must not import {sorted(FORBIDDEN[package])}: {offenders}"


def test_detector_catches_a_forbidden_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import torch\nfrom hydra import compose\n")
    assert _imported_roots(bad) >= {"torch", "hydra"}


# ---------------------------------------------------------------------------- import cycles
PACKAGES = ("solvers", "sims", "semdp")


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """Ids of the nodes under ``if TYPE_CHECKING:`` (never imported at run time)."""
    skipped: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skipped.update(id(sub) for sub in ast.walk(child))
    return skipped


def import_graph(packages: tuple[str, ...] = PACKAGES, root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the project modules it imports, at module level or inside a function alike.

    ``from pkg import name`` counts as importing ``pkg.name`` when that is a module, else
    ``pkg``; the implicit import of a parent package's ``__init__`` is not an edge (it is the
    same for every submodule). Imports under ``if TYPE_CHECKING:`` do not run and do not count.
    """
    modules = {
        _module_name(path, root): path
        for package in packages
        for path in (root / package).rglob("*.py")
    }

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        skipped = _type_checking_nodes(tree)
        targets: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in skipped:
                continue
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    module = ".".join([*base, *([node.module] if node.module else [])])
                else:
                    module = node.module or ""
                for alias in node.names:
                    child = f"{module}.{alias.name}"
                    targets.add(child if child in modules else module)
        graph[name] = {t for t in map(resolve, targets) if t is not None and t != name}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(cycles)


@pytest.mark.parametrize(
    "package",
    [
        "solvers",
        "sims",
        "semdp",
    ],
)
def test_no_import_cycles(package: str) -> None:
    cycles = [c for c in import_cycles(import_graph()) if c[0].split(".")[0] == package]
    assert not cycles, f"import cycles in {package}/ (function-local imports count): {cycles}"


def test_cycle_detector_counts_function_local_and_relative_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from pkg.a import f\n")
    (pkg / "a.py").write_text("def f():\n    from pkg import b\n    return b\n")
    (pkg / "b.py").write_text("from .a import f\n")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.a import f\n"
    )
    graph = import_graph(("pkg",), tmp_path)
    assert graph["pkg.a"] == {"pkg.b"} and graph["pkg.b"] == {"pkg.a"}
    assert graph["pkg.c"] == set()
    assert import_cycles(graph) == [["pkg.a", "pkg.b"]]


# ---------------------------------------------------------------------------- entry points
def entry_point_modules(root: Path = ROOT) -> set[str]:
    """The modules behind the console scripts of pyproject.toml (``semdp-train`` etc.)."""
    import tomllib

    scripts = tomllib.loads((root / "pyproject.toml").read_text())["project"]["scripts"]
    return {target.split(":")[0] for target in scripts.values()}


def test_library_code_does_not_import_the_apps() -> None:
    """The apps are thin: library code builds runs with semdp.build, reports with
    semdp.reporting, loads runs with semdp.evaluation, never through an app module (the graph
    counts function-local imports: see the cycle detector's test)."""
    apps = entry_point_modules()
    assert {"semdp.cli.train", "semdp.cli.eval", "semdp.cli.report"} <= apps
    offenders = {module: sorted(targets & apps)
                 for module, targets in import_graph().items()
                 if module not in apps and targets & apps}
    assert not offenders, f"library modules import app modules: {offenders}"


# ---------------------------------------------------------------------------- layers
#: The layers of the module docstring, lowest first. An entry names a module or a package (which
#: covers its submodules), except the entries of :data:`SPLIT`, which name only the package's
#: ``__init__``: their submodules are placed one by one.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("solvers", "sims"),
    ("semdp", "semdp.common", "semdp.numerics", "semdp.paths", "semdp.env_products",
     "semdp.configs", "semdp.run_config", "semdp.legacy", "semdp.envs", "semdp.zoo_data"),
    ("semdp.algos", "semdp.embedded"),
    ("semdp.build", "semdp.evaluation", "semdp.reporting", "semdp.experiments",
     "semdp.rendering", "semdp.benchmarks"),
    ("semdp.cli",),
)
SPLIT = frozenset({"semdp"})


def layer_of(module: str, layers: tuple[tuple[str, ...], ...] = LAYERS,
             split: frozenset[str] = SPLIT) -> int | None:
    """The layer of ``module``: that of the longest entry naming it or a package above it."""
    best: tuple[int, int] | None = None
    for index, names in enumerate(layers):
        for name in names:
            covers = module == name or (name not in split and module.startswith(name + "."))
            if covers and (best is None or len(name) > best[0]):
                best = (len(name), index)
    return None if best is None else best[1]


def layer_violations(graph: dict[str, set[str]], layers: tuple[tuple[str, ...], ...] = LAYERS,
                     split: frozenset[str] = SPLIT) -> list[str]:
    """``"<module> (layer i) imports <target> (layer j > i)"`` for every upward import."""
    found = []
    for module, targets in sorted(graph.items()):
        own = layer_of(module, layers, split)
        for target in sorted(targets):
            there = layer_of(target, layers, split)
            if own is not None and there is not None and there > own:
                found.append(f"{module} (layer {own}) imports {target} (layer {there})")
    return found


def test_every_module_has_a_layer() -> None:
    unplaced = sorted(m for m in import_graph() if layer_of(m) is None)
    assert not unplaced, f"modules in no layer (add them to LAYERS and the docstring): {unplaced}"


def test_no_module_imports_from_a_higher_layer() -> None:
    violations = layer_violations(import_graph())
    assert not violations, "upward imports:\n" + "\n".join(violations)


def test_layer_checker_flags_a_planted_upward_import(tmp_path: Path) -> None:
    """A tree ``lib`` < ``app.core`` < ``app.tools``: an upward import is flagged at module
    level and inside a function, not under ``if TYPE_CHECKING:``; the split package's
    ``__init__`` is in the lowest of its layers, and a module no entry names has no layer."""
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "__init__.py").write_text("")
    (tmp_path / "lib" / "geometry.py").write_text("from app.core import model\n")
    app = tmp_path / "app"
    for package in ("core", "tools"):
        (app / package).mkdir(parents=True)
        (app / package / "__init__.py").write_text("")
    (app / "__init__.py").write_text("")
    (app / "stray.py").write_text("")
    (app / "core" / "model.py").write_text("import lib.geometry\n")
    (app / "core" / "loop.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from app.tools import cli\n"
        "def run():\n    from app.tools.cli import main\n    return main\n")
    (app / "core" / "typed.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from app.tools import cli\n")
    (app / "tools" / "cli.py").write_text("from app.core import loop\ndef main(): ...\n")
    layers = (("lib",), ("app", "app.core"), ("app.tools",))
    graph = import_graph(("lib", "app"), tmp_path)
    assert layer_of("app", layers, frozenset({"app"})) == 1
    assert layer_of("app.stray", layers, frozenset({"app"})) is None
    assert layer_violations(graph, layers, frozenset({"app"})) == [
        "app.core.loop (layer 1) imports app.tools.cli (layer 2)",
        "lib.geometry (layer 0) imports app.core.model (layer 1)",
    ]


#: The on-policy algorithms' files: their speed-ups are handed in (semdp.algos.speedups).
ON_POLICY_FILES: tuple[str, ...] = tuple(f"semdp.algos.{m}" for m in (
    "on_policy", "ppo", "trpo", "trpo_lag", "cpo", "sp_ppo_lag", "lagrangian", "pid_lagrange",
    "gae", "rollout", "critic_regression", "base"))


def test_the_on_policy_algorithms_import_no_speed_up() -> None:
    """The kernels and helper processes reach an algorithm through its ``kernel`` and
    ``runners`` arguments only: the file a reader opens is the plain path."""
    graph = import_graph()
    assert set(ON_POLICY_FILES) <= set(graph)
    found = {m: sorted(t for t in graph[m]
                       if t.startswith(("semdp.algos.kernels", "semdp.algos.helpers",
                                        "semdp.algos.speedups")))
             for m in ON_POLICY_FILES}
    assert not any(found.values()), found
