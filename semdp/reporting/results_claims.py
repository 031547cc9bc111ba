"""The thesis' claims on the results page (``docs/results.md``), from
``outputs/reference/claims.yaml``.

Each claim has its verdict (reproduced / partly / not reproduced / beyond the thesis), its
budget and the folders it rests on. Its text names every number by where it lives
(:func:`fill`): ``{{cell|...}}`` a cell of a committed Markdown table, ``{{value|...}}`` a key
of a JSON or YAML file, ``{{zoo|...}}`` a zoo summary, ``{{budget|...}}`` a folder's budget
read from its kept runs, ``{{epochs_with_cost|...}}`` and ``{{config|...}}``. A number on the
page is therefore always the committed file's.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Callable
from typing import Any

from semdp.reporting.names import algorithm_name
from semdp.reporting.results_sources import (
    Sources,
    epochs_with_cost,
    evaluated,
    grouped,
    kept_runs,
    mean_se,
    number_text,
    run_steps,
    seeds_text,
    steps_text,
    table_cell,
)

VERDICTS = ("reproduced", "partly reproduced", "not reproduced", "beyond the thesis")
#: A number named in claims.yaml: ``{{kind|argument|...}}``.
PLACEHOLDER = re.compile(r"\{\{([^{}]+)\}\}")
NUMBER = re.compile(r"[−+-]?\d+(?:\.\d+)?")


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

# --- the claims section ------------------------------------------------------------------------

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
