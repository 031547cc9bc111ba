"""The results page (docs/results.md) and the README's results table are what
``python -m semdp.reporting.results_page`` builds from the committed files, and their numbers
are those files' numbers.

* the committed page and README table equal a fresh build (so neither can go stale);
* a number planted in a source file (a zoo entry's ``eval.json``, a folder's ``table.md``, the
  thesis' numbers) changes the page where that number is quoted;
* the README's results table, parsed, equals mean ± standard error computed here from each zoo
  entry's ``eval.json`` (an oracle independent of the module), and a planted wrong number in
  the README fails that check;
* the pieces: a placeholder that names a missing row, an unknown source or a folder that is
  not committed stops the build with its name.
"""

from __future__ import annotations

import json
import math
import re
import statistics
from pathlib import Path

import pytest
import yaml

from semdp.reporting import results_page as rp
from semdp.reporting.results_claims import claims, fill
from semdp.reporting.results_sources import (
    Sources,
    evaluated,
    seeds_text,
    steps_text,
    table_cell,
)

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "outputs" / "reference"
POINT_S0 = "semdp_push1/runs/ours/point_push1_s0/eval.json"


@pytest.fixture(scope="module")
def page() -> str:
    return rp.results_page(Sources())


def test_committed_page_is_what_the_command_builds(page: str) -> None:
    committed = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    assert committed == page, f"docs/results.md is stale: run {rp.COMMAND}"


def test_committed_readme_table_is_what_the_command_builds() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert rp.with_readme_table(readme, rp.readme_table(Sources())) == readme, (
        f"README.md's results table is stale: run {rp.COMMAND}")


def test_check_mode_passes_on_the_committed_files(capsys: pytest.CaptureFixture[str]) -> None:
    assert rp.main(["--check"]) == 0, capsys.readouterr().out


def _planted(relative: str, old: str, new: str) -> Sources:
    text = (REFERENCE / relative).read_text(encoding="utf-8")
    assert text.count(old) >= 1, (relative, old)
    return Sources(overrides={relative: text.replace(old, new, 1)})


def test_a_planted_wrong_return_in_an_eval_json_changes_the_page(page: str) -> None:
    record = json.loads((REFERENCE / POINT_S0).read_text())
    recorded = record["eval"]["return_mean"]
    record["eval"]["return_mean"] = recorded + 1.0
    planted = rp.results_page(Sources(overrides={POINT_S0: json.dumps(record)}))
    assert planted != page
    assert f"({recorded:.2f} / " in page
    assert f"({recorded + 1.0:.2f} / " in planted  # the per-seed cell of the headline


def test_a_planted_wrong_cell_in_a_table_md_changes_the_claim(page: str) -> None:
    section = "sp_safety_gym_policies/table.md"
    cell = table_cell((REFERENCE / section).read_text(), "Training episodes, last",
                         "PointGoal1::cost", "PPO-Lag")
    planted = rp.results_page(_planted(section, f"| {cell} |", "| 99.99 ± 0.01 |"))
    assert f"{cell} on PointGoal1" in page
    assert "99.99 ± 0.01 on PointGoal1" in planted


def test_a_planted_wrong_thesis_number_changes_the_page(page: str) -> None:
    planted = rp.results_page(_planted("thesis.yaml", "Ours: {reward: 5.69, cost: 0.00}",
                                       "Ours: {reward: 7.77, cost: 0.00}"))
    assert "5.69 / 0.00" in page and "7.77 / 0.00" in planted and "7.77" not in page


def _oracle(folder: str) -> dict[tuple[str, str], tuple[list[float], list[float]]]:
    """(method, robot) -> (rewards, costs) by seed, from zoo.yaml and the eval.json files."""
    zoo = yaml.safe_load((REFERENCE / "zoo.yaml").read_text())
    found: dict[tuple[str, str], list[tuple[int, float, float]]] = {}
    for path in zoo.values():
        if not path.startswith(folder + "/"):
            continue
        record = json.loads((REFERENCE / path / "eval.json").read_text())
        robot = re.search(r"point|car|mass", record["env"], re.I).group(0).capitalize()
        method = record["label"].split(" [eval")[0]
        found.setdefault((method, robot), []).append(
            (record["seed"], record["eval"]["return_mean"], record["eval"]["cost_mean"]))
    return {key: ([r for _, r, _ in sorted(v)], [c for _, _, c in sorted(v)])
            for key, v in found.items()}


def _mean_se(values: list[float]) -> str:
    se = statistics.stdev(values) / math.sqrt(len(values))
    return f"{statistics.fmean(values):.2f} ± {se:.2f}"


def readme_mismatches(readme: str) -> list[str]:
    """Cells of the README's results table that differ from the oracle (an empty table is a
    mismatch too)."""
    block = readme.split(rp.README_START)[1].split(rp.README_END)[0]
    rows = [line for line in block.strip().splitlines()[2:]]
    expected = {**_oracle(rp.OURS_FOLDER), **_oracle(rp.BASELINES_FOLDER)}
    thesis = yaml.safe_load((REFERENCE / "thesis.yaml").read_text())["table_3_1"]
    wrong = [] if len(rows) == 3 else [f"{len(rows)} rows, not 3"]
    for line in rows:
        cells = [c.strip().strip("*") for c in line.strip("|").split("|")]
        robot = cells[0]
        for method, cell in zip(("Ours", *rp.BASELINES), cells[1:5], strict=True):
            rewards, costs = expected[(method, robot)]
            want = f"{_mean_se(rewards)} / {_mean_se(costs)}"
            if cell != want:
                wrong.append(f"{robot} {method}: README {cell!r}, eval.json {want!r}")
        ours = thesis[f"{robot}Push1"]["Ours"]
        if cells[5] != f"{ours['reward']:.2f} / {ours['cost']:.2f}":
            wrong.append(f"{robot} thesis: README {cells[5]!r}")
    return wrong


def test_readme_results_table_equals_the_eval_json_files() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert readme_mismatches(readme) == []
    header = readme.split(rp.README_START)[1].splitlines()[1]
    assert "Ours (2 × 10⁶ steps)" in header and "(8 × 10⁶)" in header  # budgets of the runs


def test_a_planted_wrong_number_in_the_readme_table_fails() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(rp.README_START)[1].split(rp.README_END)[0]
    point = next(line for line in block.splitlines() if line.startswith("| Point"))
    first = re.search(r"\d+\.\d\d", point).group(0)
    planted = readme.replace(point, point.replace(first, f"{float(first) + 0.01:.2f}", 1))
    assert len(readme_mismatches(planted)) == 1


def test_headline_quotes_every_ours_seed_and_mean(page: str) -> None:
    for (_, robot), (rewards, costs) in _oracle(rp.OURS_FOLDER).items():
        per_seed = " / ".join(f"{r:.2f}" for r in rewards)
        assert f"**{_mean_se(rewards)} / {_mean_se(costs)}** ({per_seed})" in page, robot


def test_every_folder_is_in_the_index_once(page: str) -> None:
    index = page.split("## Every folder of")[1]
    folders = [p.name for p in REFERENCE.iterdir() if p.is_dir() and p.name != "archive"]
    folders += [f"archive/{p.name}" for p in (REFERENCE / "archive").iterdir() if p.is_dir()]
    for folder in folders:
        assert index.count(f"| `{folder}/` |") == 1, folder
        records = [REFERENCE / folder / n for n in ("COMMAND.md", "README.md")]
        record = next(p for p in records if p.is_file())  # StopIteration: no record at all
        if folder.startswith("archive/"):
            banner = record.read_text().split("\n\n")[0]
            assert banner.startswith("> **Archived.**"), folder


@pytest.mark.parametrize(
    ("template", "fault"),
    [
        ("{{cell|semdp_push1/table.md||NoSuchEnv::reward|Ours}}", "no row"),
        ("{{cell|semdp_push1/table.md||PointPush1::reward|NoSuchMethod}}", "no column"),
        ("{{cell|no_such_folder/table.md||a|b}}", "not committed"),
        ("{{nosuchkind|x}}", "unknown source"),
        ("{{value|thesis.yaml|table_3_1.NoSuchEnv}}", "does not resolve"),
        ("{{budget|toy}}", "no kept runs"),
    ],
)
def test_a_placeholder_that_does_not_resolve_stops_the_build(template: str, fault: str) -> None:
    with pytest.raises(ValueError, match=fault):
        fill(template, Sources())


def test_a_claim_on_a_folder_that_is_not_committed_stops_the_build() -> None:
    listed = yaml.safe_load((REFERENCE / "claims.yaml").read_text())
    listed[0]["folders"] = ["no_such_folder"]
    with pytest.raises(ValueError, match="no_such_folder"):
        claims(Sources(overrides={"claims.yaml": yaml.safe_dump(listed)}))


def test_formatting_oracles() -> None:
    assert steps_text(2_000_000) == "2 × 10⁶"
    assert steps_text(1_200_000) == "1.2 × 10⁶"
    assert steps_text(10_000_000) == "10⁷"
    assert steps_text(300_000) == "3 × 10⁵"
    assert seeds_text([2, 0, 1]) == "3 seeds (0-2)"
    assert seeds_text([0]) == "1 seed (0)"
    assert seeds_text([0, 2]) == "2 seeds (0, 2)"
    text = "# T\n\n| env | metric | A |\n|---|---|---|\n| X 2 m/s | reward | 1.00 ± 0.50 |\n"
    assert table_cell(text, "", "X 2 m/s::reward", "A") == "1.00 ± 0.50"


def test_a_zoo_entry_is_grouped_under_the_task_it_stepped() -> None:
    """``env=semdp_point_push1 env.task=Button1`` records the env option ``semdp_point_push1``;
    the entry belongs to PointButton1 (its config's gymnasium id), not PointPush1."""
    envs = {row.name: row.env for row in evaluated(Sources(), "semdp_button1_moving")}
    assert envs and all(env == f"{name.split('_')[1].capitalize()}Button1"
                        for name, env in envs.items()), envs
