"""``semdp-bench price``: each factor is the config edit it names, ``configured`` reproduces a
zoo entry's recorded episodes, the filter's interventions are counted (and vanish without the
filter), the summary's paired differences by hand, and a cut run continues where it stopped."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from semdp.benchmarks.price import FACTORS, SETS, Cell, evaluate_cell, main, summary_rows
from semdp.evaluation.config_edits import edited_config
from semdp.evaluation.options import parse_arguments
from semdp.evaluation.zoo import entries
from semdp.run_config import load_run_config

ENTRY = "semdp_car_push1_s1"


def _edited(factor: str):
    saved = load_run_config(entries()[ENTRY])
    return edited_config(saved, parse_arguments(list(FACTORS[factor][0])))


def test_each_factor_changes_what_it_names_and_nothing_else() -> None:
    base = _edited("configured")
    wrapper = base.env.eval_wrapper
    assert (wrapper.perception, wrapper.shield.perception) == ("lidar", "lidar")
    assert wrapper.shield.lidar_bearing_bound == "aliasing"
    assert wrapper.planner.problem.clearance == 0.5
    no_gremlins = ["hazards", "vases", "pillars", "buttons"]
    changed = {
        "planner_gt": {"env.eval_wrapper.perception": "gt"},
        "filter_gt": {"env.eval_wrapper.shield.perception": "gt"},
        "filter_unbounded": {"env.eval_wrapper.shield.lidar_bearing_bound": "none"},
        "filter_bin": {"env.eval_wrapper.shield.lidar_bearing_bound": "bin"},
        "filter_aliasing": {"env.eval_wrapper.shield.lidar_bearing_bound": "aliasing"},
        "no_filter": {"env.eval_wrapper.shield": None},
        "gt_all": {"env.eval_wrapper.perception": "gt",
                   "env.eval_wrapper.shield.perception": "gt"},
        "clearance_0.3": {"env.eval_wrapper.planner.problem.clearance": 0.3},
        "lookahead_0.2": {"env.eval_wrapper.d_min": 0.2},
        "lookahead_0.4": {"env.eval_wrapper.d_min": 0.4},
        "sampled": {},  # an evaluation setting, not a config key
        "planner_no_gremlins": {"env.eval_wrapper.obstacle_kinds": no_gremlins},
        "moving_gremlins": {"env.eval_wrapper.gremlins": "moving",
                            "env.eval_wrapper.shield.gremlins": "moving"},
        "no_gremlins": {"env.eval_wrapper.obstacle_kinds": no_gremlins,
                        "env.eval_wrapper.shield.kinds": no_gremlins},
    }
    assert set(changed) | {"configured"} == set(FACTORS)
    for factor, keys in changed.items():
        cfg = _edited(factor)
        for key, value in keys.items():
            assert OmegaConf.select(cfg, key) == value, (factor, key)
        # everything else as saved: undo the named keys and compare the whole config
        for key in keys:
            if OmegaConf.select(base, key, default="absent") == "absent":  # added by the factor
                parent, _, leaf = key.rpartition(".")
                OmegaConf.select(cfg, parent).pop(leaf)
            else:
                OmegaConf.update(cfg, key, OmegaConf.select(base, key), merge=False)
        assert cfg == base, factor


def test_configured_reproduces_the_zoo_entrys_recorded_episodes() -> None:
    recorded = json.loads((entries()[ENTRY] / "eval.json").read_text())["episodes"][:2]
    row = evaluate_cell(Cell(f"zoo:{ENTRY}", "configured", 2))
    assert (row["robot"], row["task"], row["seed"]) == ("car", "Push1", 1)
    assert row["return_mean"] == pytest.approx(np.mean([e["return"] for e in recorded]),
                                               rel=0, abs=1e-12)
    assert row["cost_mean"] == np.mean([e["cost"] for e in recorded])


def test_the_filters_interventions_are_counted_and_vanish_without_it() -> None:
    run = SETS["button1_whole_bin"][0]  # Point, Button1, whole-bin bound: many replacements
    with_filter = evaluate_cell(Cell(run, "configured", 1))
    without = evaluate_cell(Cell(run, "no_filter", 1))
    assert with_filter["shield_rate"] > 0.05
    assert 0.0 <= with_filter["shield_escape_rate"] <= with_filter["shield_rate"]
    assert without["shield_rate"] == without["shield_escape_rate"] == 0.0


def _row(run: str, robot: str, factor: str, ret: float) -> dict:
    row = {key: 0.0 for key in ("shield_rate", "shield_escape_rate", "plan_escape_rate",
                                 "plan_fallback_rate", "plan_rescue_rate", "cost_mean")}
    return {**row, "run": run, "robot": robot, "task": "Push1", "seed": 0, "factor": factor,
            "episodes": 50.0, "return_mean": ret, "episodes_with_cost": 0.0}


def test_summary_pairs_each_policy_with_its_configured_row() -> None:
    rows = [_row("a", "car", "configured", 4.0), _row("b", "car", "configured", 6.0),
            _row("a", "car", "no_filter", 5.0), _row("b", "car", "no_filter", 8.0)]
    summary = {s["factor"]: s for s in summary_rows(rows)}
    # rewards 4, 6: mean 5, sample sd sqrt(2), SE 1; differences 1, 2: mean 1.5, SE 0.5
    assert summary["configured"]["reward"] == pytest.approx((5.0, 1.0))
    assert summary["no_filter"]["reward"] == pytest.approx((6.5, 1.5))
    assert summary["no_filter"]["delta"] == pytest.approx((1.5, 0.5))
    one = summary_rows([_row("a", "car", "configured", 4.0)])[0]
    assert one["reward"][0] == 4.0 and math.isnan(one["reward"][1])


def test_a_cut_run_continues_without_repeating_finished_cells(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = [f"runs=[zoo:{ENTRY}]", "factors=[configured,no_filter]", "episodes=1",
            f"out={tmp_path}"]
    main([*args[:1], "factors=[configured]", *args[2:]])
    assert "1 cells to run (0 in" in capsys.readouterr().out
    main(args)
    printed = capsys.readouterr().out
    assert "1 cells to run (1 in" in printed
    rows = list(csv.DictReader((tmp_path / "price.csv").open()))
    assert [r["factor"] for r in rows] == ["configured", "no_filter"]
    table = (tmp_path / "price.md").read_text()
    assert "| Push1 | car | `no_filter` | 1 |" in table and (tmp_path / "price.png").is_file()
    commands = (tmp_path / "commands.txt").read_text().splitlines()
    assert len(commands) == 2 and all(c in table for c in commands)


@pytest.mark.parametrize("argv", [["set=nope"], ["factors=[nope]"], ["runs=[zoo:nope]"],
                                  ["runs=[/no/such/run]"], ["episodes=0"]])
def test_bad_arguments_exit_with_one_line(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert "\n" not in str(info.value) and str(info.value).startswith("semdp-bench")


@pytest.mark.parametrize("name", ["push1", "button1", "button1_gremlins"])
def test_the_committed_price_tables_are_rebuilt_from_their_rows(name: str) -> None:
    from semdp.benchmarks.price import markdown, read_rows
    from semdp.paths import REFERENCE_DIR

    folder = REFERENCE_DIR / "price_of_safety" / name
    committed = (folder / "price.md").read_text()
    command = committed.split("```bash\n", 1)[1].split("\n```", 1)[0]
    rows = [r for r in read_rows(folder / "price.csv") if int(r["episodes"]) == 50]
    assert committed == markdown(rows, command)
    configured = [r for r in rows if r["factor"] == "configured"]
    assert len(configured) == 9 and all(r["cost_mean"] == 0.0 for r in configured)


def test_a_sets_relative_run_is_found_from_another_directory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from semdp.benchmarks.price import locate
    from semdp.paths import REPO_ROOT

    monkeypatch.chdir(tmp_path)
    run = SETS["button1_whole_bin"][0]
    assert not Path(run).is_absolute() and locate(run) == str(REPO_ROOT / run)
    assert locate("zoo:x") == "zoo:x" and locate(str(tmp_path)) == str(tmp_path)
