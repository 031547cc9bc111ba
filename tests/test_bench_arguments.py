"""One ``key=value`` argument parser for every ``semdp-bench`` suite (and the training split)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from semdp.benchmarks import train
from semdp.benchmarks.arguments import (
    BenchArgumentError,
    as_bool,
    as_choices,
    as_float,
    as_int,
    as_list,
    parse_args,
)

DEFAULTS = {"steps": "10", "robots": "point,car", "vector": "true", "csv": "out.csv"}


def test_key_value_items_override_the_defaults() -> None:
    args = parse_args("demo", ["steps=40", "robots=[car]"], DEFAULTS)
    assert args == {**DEFAULTS, "steps": "40", "robots": "[car]"}
    assert as_int(args, "steps", minimum=1) == 40 and as_list(args["robots"]) == ["car"]
    assert as_choices(args, "robots", ("point", "car")) == ["car"]
    assert as_bool(args, "vector") is True and as_float({"x": "2.5"}, "x") == 2.5


def test_gnu_spelling_of_older_commands_is_translated() -> None:
    args = parse_args("demo", ["--steps", "7", "--robots", "point", "car", "--no-vector",
                               "--csv=x.csv"], DEFAULTS)
    assert args == {"steps": "7", "robots": "[point,car]", "vector": "false", "csv": "x.csv"}
    assert parse_args("demo", ["--vector"], DEFAULTS)["vector"] == "true"


@pytest.mark.parametrize("argv", [["stepz=3"], ["steps"], ["--bogus"]])
def test_unknown_or_malformed_arguments_name_the_suite_and_the_keys(argv: list[str]) -> None:
    with pytest.raises(BenchArgumentError, match=r"semdp-bench demo: unknown argument .*steps="):
        parse_args("demo", argv, DEFAULTS)


@pytest.mark.parametrize(
    ("call", "match"),
    [(lambda: as_int({"n": "x"}, "n"), "n must be an integer"),
     (lambda: as_int({"n": "0"}, "n", minimum=1), "n must be an integer >= 1"),
     (lambda: as_bool({"b": "maybe"}, "b"), "b must be one of"),
     (lambda: as_choices({"r": "point,boat"}, "r", ("point",)), "r must be a list of")],
)
def test_bad_values_exit_with_one_line(call, match: str) -> None:
    with pytest.raises(SystemExit, match=match):
        call()


def test_bench_train_reports_throughput_and_its_split(tmp_path: Path, capsys) -> None:
    out = tmp_path / "train.csv"
    train.main(["env=speed_limit", "algos=ppo_lag", "epochs=1", "steps_per_epoch=400",
                "vectorization=sync", "parallel_critics=false", f"out={out}"])
    (row,) = list(csv.DictReader(out.open()))
    assert row["vectorization"] == "sync" and float(row["fps"]) > 0
    split = [float(row[f"{p}_pct"]) for p in ("simulation", "policy", "storage", "update")]
    assert all(p > 0 for p in split) and sum(split) <= 100.5
    assert "upd%" in capsys.readouterr().out
