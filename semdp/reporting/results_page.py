"""The documentation's results page (``docs/results.md``), built from committed files only.

    python -m semdp.reporting.results_page            # writes docs/results.md and README's table
    python -m semdp.reporting.results_page --check    # exit 1 if either is not what it builds

Three parts, each read from ``outputs/reference/``:

* **the headline** (Table 3.1 on Push1): ``semdp-eval`` of the committed policies, Ours
  (``semdp_push1``) beside the constrained baselines (``semdp_push_8e6_policies``), per seed
  and mean ± standard error, from each zoo entry's ``eval.json`` (``zoo.yaml``); Ours'
  training epochs with cost from its runs' ``progress.csv``; the thesis' numbers from
  ``thesis.yaml``;
* **the claims** of the thesis, each with its verdict (reproduced / partly / not reproduced /
  beyond the thesis), its budget and the folder it rests on, from ``claims.yaml``. The text
  there names every number by where it lives (:func:`fill`): a cell of a committed Markdown
  table, a key of a JSON or YAML file, a zoo summary, a folder's budget read from its kept
  runs. A number on the page is therefore always the committed file's;
* **the folder index**: every folder of ``outputs/reference`` (current ones, then those under
  ``archive/``) with the zoo policies it holds and the command that rebuilds it, taken from its
  ``COMMAND.md``.

The README's results table (between ``<!-- results-table:start -->`` and ``:end -->``) is the
headline's short form and is rewritten by the same command. ``tests/test_results_page.py``
checks that the committed page and table are what this module builds.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import re
import sys
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from semdp.paths import REPO_ROOT
from semdp.reporting.names import algorithm_name, env_name, env_name_from_id
from semdp.reporting.tables import format_cell

PACKAGE_ROOT = REPO_ROOT
#: The committed results.
REFERENCE = PACKAGE_ROOT / "outputs" / "reference"
PAGE = PACKAGE_ROOT / "docs" / "results.md"
README = PACKAGE_ROOT / "README.md"
COMMAND = "python -m semdp.reporting.results_page"

#: The folders the headline reads: Ours, and the baselines at 4x Ours' steps.
OURS_FOLDER = "semdp_push1"
BASELINES_FOLDER = "semdp_push_8e6_policies"
ROBOTS = ("Point", "Car", "Mass")
BASELINES = ("CPO", "PPO Lag", "TRPO Lag")
README_START = "<!-- results-table:start -->"
README_END = "<!-- results-table:end -->"
VERDICTS = ("reproduced", "partly reproduced", "not reproduced", "beyond the thesis")
#: A number named in claims.yaml: ``{{kind|argument|...}}``.
PLACEHOLDER = re.compile(r"\{\{([^{}]+)\}\}")
NUMBER = re.compile(r"[−+-]?\d+(?:\.\d+)?")


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
            env=env_name(str(record["env"])), seed=int(record["seed"]), env_steps=steps,
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


def kept_runs(sources: Sources, folder: str) -> list[tuple[str, dict[str, Any]]]:
    """(run directory, its ``metrics.json``) of every run kept in ``folder``; ``env`` is the
    task the run stepped (its config's gymnasium id names it: ``env=semdp_point_push1
    env.task=Button1`` steps PointButton1)."""
    runs = []
    for path in sources.glob(f"{folder}/runs/**/metrics.json"):
        run_dir, metrics = str(Path(path).parent), dict(sources.data(path))
        env = env_name(str(metrics.get("env")))
        if sources.exists(f"{run_dir}/config.yaml"):
            node = (sources.data(f"{run_dir}/config.yaml") or {}).get("env") or {}
            env = env_name_from_id(str(node.get("id", ""))) or env
        metrics["env"] = env
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


# --- the numbers named in claims.yaml ------------------------------------------------------------

def _cell(sources: Sources, args: list[str]) -> str:
    """``cell|<file.md>|<section>|<row>|<column>[|<k>]``: a table cell, or its k-th number."""
    path, section, row, column, *pick = args
    text = table_cell(sources.text(path), section, row, column, where=path)
    if pick:
        numbers = NUMBER.findall(text)
        return numbers[int(pick[0]) - 1]
    return text


def _value(sources: Sources, args: list[str]) -> str:
    """``value|<file.json or .yaml>|<dotted key>[|<digits> or steps]``."""
    path, key, *shape = args
    node: Any = sources.data(path)
    for part in key.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    if shape == ["steps"]:
        return steps_text(node) if isinstance(node, int | float) else str(node)
    return number_text(node, int(shape[0]) if shape else 2)


def _config(sources: Sources, args: list[str]) -> str:
    """``config|<folder>|<dotted key>``: the key's values over the folder's kept runs'
    ``config.yaml`` (``25`` when every run has 25)."""
    folder, key = args
    values = set()
    for path in sources.glob(f"{folder}/runs/**/config.yaml"):
        node: Any = sources.data(path)
        for part in key.split("."):
            node = node[part]
        values.add(node)
    if not values:
        raise ValueError(f"results page: no kept run configs in {folder}")
    return " / ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in sorted(values))


def _zoo(sources: Sources, args: list[str]) -> str:
    """``zoo|<folder>|<method>|<env>|reward or cost``: mean ± SE over the folder's entries."""
    folder, method, env, metric = args
    group = grouped(evaluated(sources, folder)).get((method, env))
    if not group:
        raise ValueError(f"results page: no zoo entries of {method} on {env} in {folder}")
    return mean_se([getattr(r, metric) for r in group])


def _budget(sources: Sources, args: list[str]) -> str:
    """``budget|<folder>[|<method>]``: env steps and seeds of the folder's kept runs, methods
    with the same budget together, Ours first (the one method given only, without its name)."""
    folder, *only = args
    by_method: dict[str, tuple[set[int], set[int]]] = defaultdict(lambda: (set(), set()))
    for _, metrics in kept_runs(sources, folder):
        label = algorithm_name(str(metrics.get("label") or metrics.get("algo")))
        steps, seeds = by_method[label]
        steps.add(run_steps(metrics))
        seeds.add(int(metrics["seed"]))
    if only:
        by_method = {k: v for k, v in by_method.items() if k == only[0]}
    if not by_method:
        raise ValueError(f"results page: no kept runs{' of ' + only[0] if only else ''} "
                         f"in {folder}")
    same: dict[tuple[tuple[int, ...], tuple[int, ...]], list[str]] = defaultdict(list)
    for label in sorted(by_method, key=lambda name: (name != "Ours", name)):
        steps, seeds = by_method[label]
        same[(tuple(sorted(steps)), tuple(sorted(seeds)))].append(label)
    parts = []
    for (steps, seeds), labels in same.items():
        shown = " / ".join(steps_text(s) for s in steps)
        name = "" if only else ", ".join(labels) + " "
        parts.append(f"{name}{shown} env steps, {seeds_text(seeds)}")
    return "; ".join(parts)


def _epochs(sources: Sources, args: list[str]) -> str:
    """``epochs_with_cost|<folder>[|<env>[|<method>]]``: ``k of n`` (empty env: any)."""
    folder, env, method = (*args, "", "")[:3]
    with_cost, total = epochs_with_cost(sources, folder, env or None, method or None)
    return f"{with_cost:,} of {total:,}"


RESOLVERS: dict[str, Callable[[Sources, list[str]], str]] = {
    "cell": _cell, "value": _value, "zoo": _zoo, "budget": _budget, "epochs_with_cost": _epochs,
    "config": _config,
}


def fill(template: str, sources: Sources) -> str:
    """Replace every ``{{kind|...}}`` of ``template`` by the committed file's number."""

    def one(match: re.Match[str]) -> str:
        kind, *args = match.group(1).split("|")
        if kind not in RESOLVERS:
            raise ValueError(f"results page: unknown source {kind!r} in {match.group(0)}")
        try:
            return RESOLVERS[kind](sources, args)
        except (KeyError, IndexError, TypeError) as exc:
            raise ValueError(f"results page: {match.group(0)} does not resolve "
                             f"({type(exc).__name__}: {exc})") from None

    return PLACEHOLDER.sub(one, " ".join(template.split()))


# --- the page's parts ----------------------------------------------------------------------------

def _thesis_pair(cell: Mapping[str, float]) -> str:
    return f"{cell['reward']:.2f} / {cell['cost']:.2f}"


def headline(sources: Sources) -> str:
    """Table 3.1 on Push1: Ours and the baselines here, per seed and mean ± SE, and the
    thesis."""
    ours = grouped(evaluated(sources, OURS_FOLDER))
    base = grouped(evaluated(sources, BASELINES_FOLDER))
    thesis = sources.data("thesis.yaml")["table_3_1"]
    first = next(iter(ours.values()))[0]
    base_first = next(iter(base.values()))[0]
    ours_seeds = sorted({r.seed for g in ours.values() for r in g})
    base_seeds = sorted({r.seed for g in base.values() for r in g})
    lines = [
        "## Headline: Table 3.1 on Push1", "",
        f"Ours (the main job's configuration, `semdp-train experiment=semdp "
        f"env=semdp_<robot>_push1`) trained for {steps_text(first.env_steps)} env steps, "
        f"{seeds_text(ours_seeds)} per robot; the constrained baselines for "
        f"{steps_text(base_first.env_steps)} env steps, {seeds_text(base_seeds)}; cost limit 0. "
        f"The thesis trained Ours for {steps_text(thesis['steps']['Ours'])} env steps and the "
        f"baselines for {thesis['steps']['baselines']}, in MuJoCo Safety Gym; here, the pymunk "
        "replica (`sims/`). Every number here is `semdp-eval zoo:<entry>` of a committed policy "
        f"({first.episodes} single-env episodes, mean action, evaluation seeds "
        f"{min(first.seeds) - first.seed}-{max(first.seeds) - first.seed} + the run's seed): "
        "reward / cost, mean ± standard error over seeds, Ours' per seed in brackets.", "",
        "| env | Ours here | Ours' training epochs with cost | thesis' Ours | "
        + " | ".join(f"{m} here" for m in BASELINES) + " | thesis: "
        + "; ".join(BASELINES) + " |",
        "|---" * (4 + len(BASELINES) + 1) + "|",
    ]
    for robot in ROBOTS:
        env = f"{robot}Push1"
        group = ours[("Ours", env)]
        per_seed = " / ".join(f"{r.reward:.2f}" for r in group)
        with_cost, total = epochs_with_cost(sources, OURS_FOLDER, env)
        cells = [env,
                 f"**{mean_se([r.reward for r in group])} / "
                 f"{mean_se([r.cost for r in group])}** ({per_seed})",
                 f"{with_cost} of {total:,}", _thesis_pair(thesis[env]["Ours"])]
        for method in BASELINES:
            rows = base[(method, env)]
            cells.append(f"{mean_se([r.reward for r in rows])} / {mean_se([r.cost for r in rows])}")
        cells.append("; ".join(_thesis_pair(thesis[env][m]) for m in BASELINES))
        lines.append("| " + " | ".join(cells) + " |")
    violating = sum(r.cost > 0 for g in base.values() for r in g)
    n_base = sum(len(g) for g in base.values())
    ours_cost = sum(r.cost > 0 for g in ours.values() for r in g)
    lines += [
        "",
        f"Policies with cost in some evaluation episode: Ours {ours_cost} of "
        f"{sum(len(g) for g in ours.values())}, the baselines {violating} of {n_base}. The "
        "baselines "
        "are far from converged at this budget (a quarter of the thesis' steps or less), so the "
        "reward gap between Ours and them here overstates the thesis'. Folders: "
        f"`outputs/reference/{OURS_FOLDER}/` and `outputs/reference/{BASELINES_FOLDER}/`.",
        "",
    ]
    lines += [f"![Training curves of Ours on {r}Push1, mean ± SE over seeds]"
              f"(figures/{OURS_FOLDER}/curves_{r}Push1.png)" for r in ROBOTS if
              sources.exists(f"{OURS_FOLDER}/curves_{r}Push1.png")]
    return "\n".join(lines) + "\n"


def readme_table(sources: Sources) -> str:
    """The headline's short form for the README: reward / cost, mean ± SE over seeds."""
    ours = grouped(evaluated(sources, OURS_FOLDER))
    base = grouped(evaluated(sources, BASELINES_FOLDER))
    thesis = sources.data("thesis.yaml")["table_3_1"]
    o_steps = steps_text(next(iter(ours.values()))[0].env_steps)
    b_steps = steps_text(next(iter(base.values()))[0].env_steps)
    t_steps = steps_text(thesis["steps"]["Ours"])
    lines = [f"| Push1, reward / cost | Ours ({o_steps} steps) | "
             + " | ".join(f"{m} ({b_steps})" for m in BASELINES) + f" | thesis' Ours ({t_steps}) |",
             "|---" * (2 + len(BASELINES) + 1) + "|"]
    for robot in ROBOTS:
        env = f"{robot}Push1"
        cells = [robot]
        for group in [ours[("Ours", env)], *(base[(m, env)] for m in BASELINES)]:
            cells.append(f"{mean_se([r.reward for r in group])} / "
                         f"{mean_se([r.cost for r in group])}")
        cells[1] = f"**{cells[1]}**"
        cells.append(_thesis_pair(thesis[env]["Ours"]))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def claims(sources: Sources) -> str:
    """The thesis' claims with their verdicts: a summary table, then the evidence."""
    summary = ["## The thesis' claims, one by one", "",
               "Verdicts: *reproduced*, *partly reproduced*, *not reproduced*, or *beyond the "
               "thesis* (a result the thesis does not claim). Each rests on the folders named, "
               "at the budget given; the numbers are those of the folders' committed files.", "",
               "| # | claim | thesis | verdict | budget | folders |", "|---|---|---|---|---|---|"]
    details = []
    for number, claim in enumerate(listed_claims(sources), start=1):
        text = {key: fill(claim[key], sources) for key in ("claim", "thesis", "budget",
                                                            "evidence")}
        folders = ", ".join(f"`outputs/reference/{f}/`" for f in claim["folders"])
        summary.append(f"| [{number}](#claim-{number}) | {text['claim']} | {text['thesis']} | "
                       f"**{claim['verdict']}** | {text['budget']} | {folders} |")
        details += [f"### {number}. {text['claim']} {{#claim-{number}}}", "",
                    f"*{text['thesis']}.* **{claim['verdict'].capitalize()}**; "
                    f"{text['budget']}; {folders}.", "", text["evidence"], ""]
    return "\n".join(summary) + "\n\n" + "\n".join(details)


def listed_claims(sources: Sources) -> list[dict[str, Any]]:
    """``claims.yaml``, checked: known verdicts, committed folders."""
    listed = sources.data("claims.yaml")
    for number, claim in enumerate(listed, start=1):
        if claim["verdict"] not in VERDICTS:
            raise ValueError(f"claims.yaml: claim {number} has verdict {claim['verdict']!r}, "
                             f"not one of {VERDICTS}")
        for folder in claim["folders"]:
            if not (sources.root / folder).is_dir():
                raise ValueError(f"claims.yaml: claim {number} rests on outputs/reference/"
                                 f"{folder}, which is not committed")
    return listed


def _command_md_facts(text: str, record: str = "COMMAND.md") -> tuple[str, str | None, str]:
    """(title, runs line, rebuild command) of a folder's record (its COMMAND.md, else its
    README.md, named by ``record``)."""
    title = next((line[2:].strip() for line in text.splitlines() if line.startswith("# ")), "")
    title = re.sub(r"^Reference:\s*", "", title)
    runs = re.search(r"^- Runs: (\d+) \((\d+) completed\)", text, re.M)
    runs_text = f"{runs.group(1)}" if runs else None
    rebuild = re.search(r"rebuild or extend this folder with `([^`]+)`", text)
    if rebuild:
        return title, runs_text, rebuild.group(1).replace(" [more sweeps]", "")
    block = re.search(r"^```(?:bash)?\n(.*?)^```", text, re.M | re.S)
    commands = [line.split("  #")[0].strip() for line in (block.group(1) if block else "")
                .splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not commands:  # a command named in the prose
        commands = re.findall(r"`((?:semdp-|python -m )[^`]+)`", text)[:1]
    if not commands:
        return title, runs_text, f"see {record}"
    more = f" (and {len(commands) - 1} more in {record})" if len(commands) > 1 else ""
    return title, runs_text, commands[0] + more


def _banner(text: str) -> str:
    """The archive banner: the first paragraph, when it is a quote."""
    first = text.split("\n\n")[0]
    return " ".join(line.lstrip("> ") for line in first.splitlines()) if first.startswith(">") \
        else ""


def _replaced_by(banner: str) -> str:
    """The folders an archive banner names after 'replaced by'."""
    found = re.search(r"replaced by(.*?)(?:\.\s|\.$|$)", banner, re.I | re.S)
    names = re.findall(r"`(?:\.\./)*((?:archive/)?[a-z0-9_]+(?:/[a-z_]+\.md)?)`",
                       found.group(1) if found else "")
    return ", ".join(f"`{n}`" for n in dict.fromkeys(names))


def _clause(text: str) -> str:
    """A paragraph's first clause (up to its first colon or semicolon), links as their text."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return re.split(r"[:;]\s", text, maxsplit=1)[0].strip()


def _first_prose(text: str) -> str:
    """The first paragraph of a COMMAND.md that is prose (not a heading, list, table, quote
    or code)."""
    body = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    for paragraph in body.split("\n\n"):
        paragraph = paragraph.strip()
        if paragraph and not paragraph.startswith(("#", "-", "|", ">", "`", "Produced")):
            return " ".join(paragraph.split())
    return ""


def _runs_summary(sources: Sources, folder: str) -> str:
    """``methods × envs`` of the folder's kept runs ('' without runs)."""
    methods, envs = set(), set()
    for _, metrics in kept_runs(sources, folder):
        methods.add(algorithm_name(str(metrics.get("label") or metrics.get("algo"))))
        envs.add(str(metrics["env"]))
    if not methods:
        return ""
    ordered = sorted(methods, key=lambda name: (name != "Ours", name))
    return f"{', '.join(ordered)} × {', '.join(sorted(envs))}"


def folder_index(sources: Sources) -> str:
    """Every folder of outputs/reference: what, claims, status, runs, zoo policies, rebuild."""
    zoo = zoo_entries(sources)
    resting: dict[str, list[int]] = defaultdict(list)
    for number, claim in enumerate(listed_claims(sources), start=1):
        for folder in claim["folders"]:
            resting[folder].append(number)
    lines = ["## Every folder of `outputs/reference/`", "",
             "Current folders first, then the archived ones (`outputs/reference/archive/`: each "
             "`COMMAND.md`, or `README.md` where the folder has no commands of its own, opens "
             "with what the folder was, why it is archived and what replaces it). *Claims*: the "
             "claims above that rest on it; *runs*: the runs its report counts; *zoo*: its "
             "policies in `zoo.yaml` (`semdp-eval zoo:<entry>`); *rebuild*: the command, from "
             "that file.", "",
             "| folder | what | claims | status | runs | zoo | rebuild |",
             "|---|---|---|---|---|---|---|"]
    root = sources.root
    folders = sorted(p.name for p in root.iterdir() if p.is_dir() and p.name != "archive")
    folders += sorted(f"archive/{p.name}" for p in (root / "archive").iterdir() if p.is_dir())
    for folder in folders:
        record = next((name for name in ("COMMAND.md", "README.md")
                       if sources.exists(f"{folder}/{name}")), "COMMAND.md")
        text = sources.text(f"{folder}/{record}") if sources.exists(f"{folder}/{record}") else ""
        title, runs, rebuild = _command_md_facts(text, record)
        banner = _banner(text)
        if not title or title.strip("`") == folder.split("/")[-1]:
            title = (_clause(banner.removeprefix("**Archived.** "))
                     or _runs_summary(sources, folder) or _clause(_first_prose(text)))
        status = "current"
        if folder.startswith("archive/"):
            replaced = _replaced_by(banner)
            status = "archived" + (f"; replaced by {replaced}" if replaced else "")
        held = sorted(name for name, path in zoo.items() if path.startswith(folder + "/"))
        policies = ("–" if not held else f"{len(held)}: `{held[0]}`"
                    + (f" … `{held[-1]}`" if len(held) > 1 else ""))
        numbers = ", ".join(f"[{n}](#claim-{n})" for n in resting.get(folder, [])) or "–"
        rebuild = rebuild.replace("|", "\\|")
        lines.append(f"| `{folder}/` | {title} | {numbers} | {status} | {runs or '–'} | "
                     f"{policies} | `{rebuild}` |")
    return "\n".join(lines) + "\n"


def results_page(sources: Sources | None = None) -> str:
    """The whole page."""
    sources = sources or Sources()
    intro = [
        "# Results", "",
        f"<!-- Generated by `{COMMAND}` from outputs/reference/; do not edit by hand. -->", "",
        "What this project's runs show against the thesis (\"Exploring Safe Reinforcement "
        "Learning for Sequential Decision Making\"; the SEMDP method is also the paper "
        "arXiv:2310.06903, see `CITATION.cff`). Every number on this page comes from a "
        "committed file of `outputs/reference/`; the page is rebuilt with", "",
        "```bash", COMMAND, "```", "",
        "and `tests/test_results_page.py` fails when the committed page differs from what the "
        "command builds. The thesis' numbers quoted are in `outputs/reference/thesis.yaml`, the "
        "claims and their verdicts in `outputs/reference/claims.yaml`. How the folders were "
        "made (commands, machines, wall times) is in each folder's `COMMAND.md`; earlier "
        "results and their history are in `CHANGELOG.md`.", "",
    ]
    return ("\n".join(intro) + "\n" + headline(sources) + "\n" + claims(sources) + "\n"
            + folder_index(sources))


def with_readme_table(readme: str, table: str) -> str:
    """``readme`` with the block between the results-table markers replaced by ``table``."""
    start, end = readme.find(README_START), readme.find(README_END)
    if start < 0 or end < start:
        raise ValueError(f"README.md lacks the markers {README_START} ... {README_END}")
    return readme[:start + len(README_START)] + "\n" + table + readme[end:]


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) docs/results.md and the README's results table."""
    parser = argparse.ArgumentParser(prog=COMMAND, description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if the committed files differ")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    sources = Sources()
    page = results_page(sources)
    readme = with_readme_table(README.read_text(encoding="utf-8"), readme_table(sources))
    stale = [p for p, text in ((PAGE, page), (README, readme))
             if p.read_text(encoding="utf-8") != text]
    if args.check:
        for path in stale:
            print(f"{path.relative_to(PACKAGE_ROOT)} is stale: run {COMMAND}")
        return 1 if stale else 0
    PAGE.write_text(page, encoding="utf-8")
    README.write_text(readme, encoding="utf-8")
    for path in (PAGE, README):
        print(f"{'wrote' if path in stale else 'unchanged'} {path.relative_to(PACKAGE_ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
