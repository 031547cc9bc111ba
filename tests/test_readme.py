"""The README is a one-page guide whose numbers are the committed files' numbers.

* at most 120 lines; its two commands are exactly what CI runs (``.ci/run``) and the main job;
* every number of its prose is checked: the main job's budget, evaluation episodes and k
  against the composed config, the results paragraph against the zoo's ``eval.json`` files and
  ``thesis.yaml``, the citation against ``CITATION.cff``, the Python version against
  ``pyproject.toml``. A number that no check covers fails the test, so a new number cannot be
  added unchecked (the results table between its markers is checked in
  ``tests/test_results_page.py``; the thesis' equation, figure and table numbers are
  references, not quoted values);
* planted: a wrong number and an unchecked new number each fail.
"""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from semdp.configs import compose_config
from semdp.reporting import results_page as rp
from semdp.reporting.results_claims import _config
from semdp.reporting.results_sources import Sources, steps_text

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "outputs" / "reference"
README = ROOT / "README.md"
#: The thesis' own numbering (sections, equations, algorithms, figures, tables, appendices).
REFERENCE_NUMBER = re.compile(
    r"\b(?:Eqs?|Alg|Figs?|Table|App)\.? (?:[A-Z]\.)?\d+(?:\.\d+)*(?:[–-](?:[A-Z]\.)?\d+(?:\.\d+)*)?"
    r"|§\d+(?:\.\d+)*")
#: Numbers that state behaviour rather than quote a measurement (tested where the behaviour is).
LITERALS = ("exit status 1",)
NUMBER = re.compile(r"(?<![A-Za-z])\d+(?:[.,]\d+)*")  # not a name's digits (Push1)


def _main_job() -> dict:
    return OmegaConf.to_container(compose_config("train", ["experiment=semdp"]), resolve=True)


def _ours_evals() -> list[dict]:
    zoo = yaml.safe_load((REFERENCE / "zoo.yaml").read_text())
    return [json.loads((REFERENCE / path / "eval.json").read_text())
            for path in zoo.values() if path.startswith(rp.OURS_FOLDER + "/")]


def _baseline_cost_limit() -> str:
    return _config(Sources(), [rp.BASELINES_FOLDER, "cost_limit"])


def _thesis_steps() -> int:
    return yaml.safe_load((REFERENCE / "thesis.yaml").read_text())["table_3_1"]["steps"]["Ours"]


def _citation() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text())["preferred-citation"]


#: Each phrase the README quotes, built from the file it comes from.
FACTS: dict[str, Callable[[], str]] = {
    "main job's env steps": lambda: (
        f"for {steps_text(_main_job()['total_steps'] * _main_job()['env']['wrapper']['k'])} "
        "env steps"),
    "main job's evaluation episodes": lambda: (
        f"evaluates the policy over {_main_job()['final_eval_episodes']} episodes"),
    "SEMDP's k": lambda: f"k = {_main_job()['env']['wrapper']['k']} steps",
    "main job's envs": lambda: f"({_main_job()['env']['num_envs']} lockstep envs",
    "results: Ours' cost": lambda: (
        "Ours keeps cost 0 on every robot and seed" if all(
            e["eval"]["cost_mean"] == 0 for e in _ours_evals()) else "Ours has cost"),
    "results: episodes and seeds": lambda: (
        f"{_ours_evals()[0]['eval']['episodes']} episodes each, mean ± standard error over "
        f"{len({e['seed'] for e in _ours_evals()})} seeds, cost limit {_baseline_cost_limit()})"),
    "results: thesis' steps": lambda: (
        f"the thesis trained for {steps_text(_thesis_steps())} env steps"),
    "Python version": lambda: (
        "Python " + tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
        ["requires-python"].removeprefix(">=") + " or later"),
    "citation year": lambda: f"year    = {{{_citation()['year']}}}",
    "citation arXiv id": lambda: (
        f"journal = {{arXiv preprint {_citation()['identifiers'][0]['value']}}}"),
}


def _prose(readme: str) -> str:
    """The README without fences, the generated table, code spans, link targets and the
    thesis' own numbering."""
    text = readme
    if rp.README_START in text:
        text = text.split(rp.README_START)[0] + text.split(rp.README_END)[1]
    text = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    text = re.sub(r"`[^`\n]+`", "", text)
    text = re.sub(r"^\d+\. ", "", text, flags=re.M)  # an ordered list's markers
    for literal in LITERALS:
        text = text.replace(literal, "")
    text = re.sub(r"\]\([^)]*\)", "]", text)
    text = REFERENCE_NUMBER.sub("", text)
    return text.replace("2-D", "")


def _flat(text: str) -> str:
    return " ".join(text.split())


def unchecked_numbers(readme: str) -> list[str]:
    """Facts the README does not quote as the files say ('missing: ...'), then the numbers of
    its prose that no fact covers."""
    phrases = {name: _flat(fact()) for name, fact in FACTS.items()}
    flat = _flat(readme)
    problems = [f"missing: {name}: {phrase!r}" for name, phrase in phrases.items()
                if phrase not in flat]
    prose = _flat(_prose(readme))
    for phrase in phrases.values():
        prose = prose.replace(_flat(_prose(phrase)), "")
    return problems + NUMBER.findall(prose)


def test_readme_is_one_page() -> None:
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 120


def test_the_two_commands_are_what_ci_runs() -> None:
    readme = README.read_text(encoding="utf-8")
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if line.startswith("pip install")]
    assert ci == ['pip install -c .ci/constraints-cpu.txt -e ".[dev]" && python -m pytest']
    assert f"{ci[0]}          # the tests" in readme
    assert ("pip install -c .ci/constraints-cpu.txt -e . && semdp-train experiment=semdp     "
            "# the main job") in readme


def test_every_number_of_the_readme_is_checked() -> None:
    assert unchecked_numbers(README.read_text(encoding="utf-8")) == []


@pytest.mark.parametrize(
    ("old", "new"),
    [("1.5 × 10⁶ env steps", "2 × 10⁶ env steps"),      # a wrong budget
     ("over 50 episodes", "over 100 episodes"),           # a wrong episode count
     ("over 3 seeds", "over 5 seeds"),                    # a wrong seed count
     ("year    = {2023}", "year    = {2024}"),           # a wrong citation
     ("a CPU is enough.", "a CPU is enough; it takes 4 min.")],  # a new, unchecked number
    ids=["budget", "episodes", "seeds", "citation", "unchecked"],
)
def test_a_planted_number_fails(old: str, new: str) -> None:
    readme = README.read_text(encoding="utf-8")
    assert old in readme
    assert unchecked_numbers(readme.replace(old, new, 1)) != []
