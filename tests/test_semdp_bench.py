"""``semdp-bench semdp``: the SEMDP training throughput and its time split, on a seconds-long
configuration of the main job (both loops)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from semdp.benchmarks.semdp import main

TINY = ["env=semdp_mass_push1", "steps=32", "budget.steps_per_epoch=16",
        "algo.learning_starts=16", "algo.batch_size=16", "algo.hidden_sizes=[16,16]",
        "algo.buffer_size=1000", "++env.kwargs.max_episode_steps=200"]


@pytest.mark.parametrize("loop", [["loop=sequential"], ["env.num_envs=2", "algo.learner=inline"]],
                         ids=["sequential", "lockstep-inline"])
def test_semdp_bench_prints_throughput_and_time_split(
    loop: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "semdp.csv"
    main([*TINY, *loop, f"out={out}"])
    text = capsys.readouterr().out
    assert "high-level steps/s" in text
    for part in ("perception", "planning", "following", "simulation", "learning", "other"):
        assert f"  {part}" in text
    with out.open() as f:
        (row,) = list(csv.DictReader(f))
    assert int(row["high_level_steps"]) == 32 and int(row["env_steps"]) == 320
    parts = sum(float(row[f"{p}_s"]) for p in ("perception", "planning", "following",
                                                "simulation", "learning", "other"))
    assert parts == pytest.approx(float(row["wall_s"]), rel=0.02)
    assert float(row["learning_s"]) > 0  # updates ran in the timed steps


def test_semdp_bench_rejects_a_bare_word() -> None:
    with pytest.raises(SystemExit, match="key=value"):
        main(["fast"])


def test_semdp_bench_random_times_the_envs_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "semdp.csv"
    main([*TINY, "env.num_envs=2", "algo.learner=process", "random=true", f"out={out}"])
    text = capsys.readouterr().out
    assert "of random actions" in text and "learner process" not in text
    with out.open() as f:
        (row,) = list(csv.DictReader(f))
    # one untimed epoch of 16, then the 32 timed steps; no learner was started, nothing learnt
    assert int(row["high_level_steps"]) == 32 and int(row["env_steps"]) == 320
    assert row["learner"] == "none (random actions)" and float(row["learning_s"]) == 0.0
    assert "algo.learning_starts=" in row["overrides"]
