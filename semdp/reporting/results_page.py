"""The documentation's results page (``docs/results.md``), built from committed files only.

    python -m semdp.reporting.results_page            # writes docs/results.md and README's table
    python -m semdp.reporting.results_page --check    # exit 1 if either is not what it builds

Three parts, each read from ``outputs/reference/`` (through
:class:`~semdp.reporting.results_sources.Sources`):

* **the headline** (Table 3.1 on Push1), built here: ``semdp-eval`` of the committed policies,
  Ours (``semdp_push1``) beside the constrained baselines (``semdp_push_8e6_policies``), per
  seed and mean ± standard error, from each zoo entry's ``eval.json`` (``zoo.yaml``); Ours'
  training epochs with cost from its runs' ``progress.csv``; the thesis' numbers from
  ``thesis.yaml``;
* **the claims** of the thesis, each with its verdict, its budget and the folder it rests on,
  from ``claims.yaml`` (:mod:`semdp.reporting.results_claims`, whose :func:`fill` reads every
  number the text names from the committed file that holds it);
* **the folder index** (:mod:`semdp.reporting.results_index`): every folder of
  ``outputs/reference`` (current ones, then those under ``archive/``) with the zoo policies it
  holds and the command that rebuilds it, taken from its ``COMMAND.md``.

The README's results table (between ``<!-- results-table:start -->`` and ``:end -->``) is the
headline's short form and is rewritten by the same command. ``tests/test_results_page.py``
checks that the committed page and table are what this module builds.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping

from semdp.paths import REPO_ROOT
from semdp.reporting.results_claims import claims
from semdp.reporting.results_index import folder_index
from semdp.reporting.results_sources import (
    Sources,
    epochs_with_cost,
    evaluated,
    grouped,
    mean_se,
    seeds_text,
    steps_text,
)

PACKAGE_ROOT = REPO_ROOT
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
