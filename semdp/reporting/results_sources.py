"""The committed results of ``outputs/reference/``, read for the results page
(``docs/results.md``, built by :mod:`semdp.reporting.results_page`).

One door to the committed files (:class:`Sources`, where a test plants a changed file), the
formatting of the page's numbers (env steps, seeds, mean ± standard error), and the readers of
what the folders hold: a cell of a committed Markdown table, the zoo entries' recorded
``semdp-eval`` (the thesis' Table 3.1 measure), the kept runs and their training epochs with
cost.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from semdp.paths import REPO_ROOT
from semdp.reporting.names import algorithm_name, trained_env
from semdp.reporting.tables import format_cell

#: The committed results.
REFERENCE = REPO_ROOT / "outputs" / "reference"


@dataclass
class Sources:
    """The committed files, read through one door (a test plants a changed file in
    ``overrides``: a path relative to ``root`` -> its text)."""

    root: Path = REFERENCE
    overrides: dict[str, str] = field(default_factory=dict)
    _parsed: dict[str, Any] = field(default_factory=dict, repr=False)

    def text(self, relative: str) -> str:
        if relative in self.overrides:
            return self.overrides[relative]
        path = self.root / relative
        if not path.is_file():
            raise ValueError(f"results page: outputs/reference/{relative} is not committed")
        return path.read_text(encoding="utf-8")

    def data(self, relative: str) -> Any:
        """A JSON or YAML file, parsed once (treat the result as read-only)."""
        if relative not in self._parsed:
            text = self.text(relative)
            self._parsed[relative] = (json.loads(text) if relative.endswith(".json")
                                      else yaml.load(text, Loader=_YAML_LOADER))
        return self._parsed[relative]

    def exists(self, relative: str) -> bool:
        return relative in self.overrides or (self.root / relative).is_file()

    def glob(self, pattern: str) -> list[str]:
        found = {str(p.relative_to(self.root)) for p in self.root.glob(pattern)}
        return sorted(found)


# --- formatting ----------------------------------------------------------------------------------

_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def steps_text(steps: float) -> str:
    """``2000000`` -> ``2 × 10⁶``, ``1200000`` -> ``1.2 × 10⁶``, ``150000`` -> ``1.5 × 10⁵``."""
    if steps <= 0:
        return str(steps)
    exponent = math.floor(math.log10(steps))
    mantissa = round(steps / 10**exponent, 2)
    head = "" if mantissa == 1 else f"{mantissa:g} × "
    return f"{head}10{str(exponent).translate(_SUPERSCRIPT)}"


def seeds_text(seeds: Iterable[int]) -> str:
    """``[0, 1, 2]`` -> ``3 seeds (0-2)``; ``[0]`` -> ``1 seed (0)``."""
    seeds = sorted(set(seeds))
    if not seeds:
        return "no seeds"
    contiguous = seeds == list(range(seeds[0], seeds[-1] + 1)) and len(seeds) > 2
    listed = f"{seeds[0]}-{seeds[-1]}" if contiguous else ", ".join(map(str, seeds))
    return f"{len(seeds)} seed{'s' * (len(seeds) > 1)} ({listed})"


def number_text(value: Any, digits: int = 2) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}" if abs(value) >= 10_000 else str(value)
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def mean_se(values: list[float]) -> str:
    return format_cell(values, len(values))


# --- the committed files -------------------------------------------------------------------------

def markdown_tables(text: str) -> list[tuple[str, list[str], list[list[str]]]]:
    """Every table of a Markdown text: (the heading above it, header cells, body rows)."""
    tables, heading, lines = [], "", text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
        elif line.startswith("|") and i + 1 < len(lines) and re.match(
                r"^\|[\s:|-]+\|$", lines[i + 1].strip()):
            header = _cells(line)
            rows, i = [], i + 2
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append(_cells(lines[i].strip()))
                i += 1
            tables.append((heading, header, rows))
            continue
        i += 1
    return tables


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def table_cell(text: str, section: str, row: str, column: str, where: str = "") -> str:
    """The cell of ``column`` in the row whose leading cells are ``row`` ('::'-separated) of
    the first table under a heading that contains ``section`` (empty: the first table)."""
    keys = row.split("::")
    for heading, header, rows in markdown_tables(text):
        if section.lower() not in heading.lower():
            continue
        if column not in header:
            raise ValueError(f"{where}: no column {column!r} under {heading!r} ({header})")
        for cells in rows:
            if cells[:len(keys)] == keys:
                return cells[header.index(column)]
        raise ValueError(f"{where}: no row {row!r} under {heading!r}")
    raise ValueError(f"{where}: no table under a heading with {section!r}")


def zoo_entries(sources: Sources) -> dict[str, str]:
    """``zoo.yaml``: entry -> run directory (relative to outputs/reference)."""
    return {str(k): str(v) for k, v in (sources.data("zoo.yaml") or {}).items()}


@dataclass(frozen=True)
class Evaluated:
    """One zoo entry's recorded ``semdp-eval``."""

    name: str
    run_dir: str
    method: str
    env: str
    seed: int
    env_steps: int
    reward: float
    cost: float
    episodes: int
    seeds: tuple[int, ...]


def evaluated(sources: Sources, folder: str) -> list[Evaluated]:
    """The zoo entries kept in ``folder``, with their ``eval.json`` (low-level env steps: a
    Safety-Embedded MDP run's high-level steps times its k, from ``metrics.json``)."""
    found = []
    for name, run_dir in sorted(zoo_entries(sources).items()):
        if not run_dir.startswith(folder + "/"):
            continue
        record = sources.data(f"{run_dir}/eval.json")
        metrics = sources.data(f"{run_dir}/metrics.json")
        steps = int((metrics.get("semdp") or {}).get("train_low_level_steps")
                    or record["env_steps"])
        found.append(Evaluated(
            name=name, run_dir=run_dir, method=str(record["label"]).split(" [eval")[0],
            env=stepped_env(sources, run_dir, str(record["env"])), seed=int(record["seed"]),
            env_steps=steps,
            reward=float(record["eval"]["return_mean"]), cost=float(record["eval"]["cost_mean"]),
            episodes=int(record["eval"]["episodes"]),
            seeds=tuple(int(s) for s in record["settings"]["seeds"])))
    if not found:
        raise ValueError(f"results page: no zoo entry in outputs/reference/{folder}")
    return found


def grouped(rows: list[Evaluated]) -> dict[tuple[str, str], list[Evaluated]]:
    """(method, env) -> its entries by seed."""
    groups: dict[tuple[str, str], list[Evaluated]] = defaultdict(list)
    for row in rows:
        groups[(row.method, row.env)].append(row)
    return {key: sorted(group, key=lambda r: r.seed) for key, group in groups.items()}


def stepped_env(sources: Sources, run_dir: str, recorded: str) -> str:
    """The task a run stepped, for tables: its config's gymnasium id names it
    (``env=semdp_point_push1 env.task=Button1`` steps PointButton1), else the ``recorded`` env
    option's name."""
    node = {}
    if sources.exists(f"{run_dir}/config.yaml"):
        node = (sources.data(f"{run_dir}/config.yaml") or {}).get("env") or {}
    return trained_env(str(node.get("id", "")), recorded)


def kept_runs(sources: Sources, folder: str) -> list[tuple[str, dict[str, Any]]]:
    """(run directory, its ``metrics.json``) of every run kept in ``folder``; ``env`` is the
    task the run stepped (:func:`stepped_env`)."""
    runs = []
    for path in sources.glob(f"{folder}/runs/**/metrics.json"):
        run_dir, metrics = str(Path(path).parent), dict(sources.data(path))
        metrics["env"] = stepped_env(sources, run_dir, str(metrics.get("env")))
        runs.append((run_dir, metrics))
    return runs


def run_steps(metrics: Mapping[str, Any]) -> int:
    """A run's env steps (low-level for a Safety-Embedded MDP run)."""
    return int((metrics.get("semdp") or {}).get("train_low_level_steps") or metrics["env_steps"])


def epochs_with_cost(sources: Sources, folder: str, env: str | None = None,
                     method: str | None = None) -> tuple[int, int]:
    """(epochs whose training episodes had cost, epochs) over the runs kept in ``folder``
    (those on ``env`` and of ``method`` only, if given)."""
    with_cost = total = 0
    for run_dir, metrics in kept_runs(sources, folder):
        if env is not None and metrics["env"] != env:
            continue
        if method is not None and algorithm_name(str(metrics.get("label"))) != method:
            continue
        for row in csv.DictReader(io.StringIO(sources.text(f"{run_dir}/progress.csv"))):
            total += 1
            with_cost += bool(row["ep_cost"]) and float(row["ep_cost"]) > 0
    return with_cost, total
