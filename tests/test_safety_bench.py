"""``semdp-bench safety`` on a small slice: the adversarial (hazard-seeking) and wrong-button
policies' aims (planted layouts), zero cost under them with the evaluation and the training
configuration, and the written table."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from semdp.benchmarks.safety import build_semdp_env, main, make_policy


def test_adversarial_policy_aims_at_the_nearest_hazard() -> None:
    env = build_semdp_env("mass", "Goal1", "eval")
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [(1.0, 0.0), (-1.5, 1.5)],
              "vases": [(1.5, -1.5)], "goal": (-1.5, -1.5)}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    action = make_policy("adversarial", env, seed=0)(obs)
    # 1 m ahead in the ego frame, in units of the 2 m subgoal scale
    np.testing.assert_allclose(action, [0.5, 0.0], atol=1e-9)
    with pytest.raises(ValueError, match="policy"):
        make_policy("greedy", env, seed=0)


def test_wrong_button_policy_aims_at_the_nearest_button_that_is_not_the_goal() -> None:
    env = build_semdp_env("mass", "Button1", "eval")
    assert "buttons" in env.obstacle_kinds and env.unwrapped.task == "button"
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [], "gremlins": [],
              "buttons": [(0.6, 0.0), (0.0, 1.2), (-1.5, 1.5), (1.5, -1.5)]}
    for seed, goal, aim in ((0, 3, [0.3, 0.0]), (2, 0, [0.0, 0.6])):
        obs, _ = env.reset(seed=seed, options={"layout": layout})
        assert env.unwrapped.goal_button == goal
        # the nearest button, unless it is the goal (then the next one), in 2 m units
        np.testing.assert_allclose(make_policy("wrong_button", env, seed=0)(obs), aim,
                                   atol=1e-9)


def test_the_wrong_button_policy_has_cells_on_the_button_tasks_only() -> None:
    with pytest.raises(SystemExit, match="no cell"):
        main(["tasks=Goal1,Push2", "policies=wrong_button"])


def test_small_slice_has_no_cost_and_writes_the_table(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    main(["robots=mass", "tasks=Push1", "policies=adversarial", "configs=eval,train",
          "episodes=1", "workers=1", "seed=7100", f"out={tmp_path}"])
    captured = capsys.readouterr()
    printed = captured.out
    assert "2 cells, 2 episodes" in printed and "0 with cost" in printed
    progress = captured.err.splitlines()
    assert [line.split(":")[0] for line in progress] == ["[1/2] mass Push1 adversarial eval",
                                                         "[2/2] mass Push1 adversarial train"]
    assert all("0/1 episodes with cost" in line for line in progress)
    rows = list(csv.DictReader((tmp_path / "safety.csv").open()))
    assert [(r["config"], r["policy"]) for r in rows] == [("eval", "adversarial"),
                                                          ("train", "adversarial")]
    for row in rows:
        assert int(row["episodes_with_cost"]) == 0 and float(row["cost_steps_total"]) == 0.0
        assert int(row["plans"]) == 100  # 1000 low-level steps / k = 10
    # cut short after the first cell: the same command runs only the second
    first = (tmp_path / "cells.jsonl").read_text().splitlines()[0]
    (tmp_path / "cells.jsonl").write_text(first + "\n")
    (tmp_path / "safety.csv").unlink()
    main(["robots=mass", "tasks=Push1", "policies=adversarial", "configs=eval,train",
          "episodes=1", "workers=1", "seed=7100", f"out={tmp_path}"])
    captured = capsys.readouterr()
    assert "1 of 2 cells read back" in captured.err
    assert [line.split(":")[0] for line in captured.err.splitlines()[1:]] == [
        "[2/2] mass Push1 adversarial train"]
    again = list(csv.DictReader((tmp_path / "safety.csv").open()))
    assert again[0] == rows[0]  # read back as written
    timing = "high_level_steps_per_s"
    assert {k: v for k, v in again[1].items() if k != timing} == {
        k: v for k, v in rows[1].items() if k != timing}  # run again: the same episodes


def test_bad_arguments_exit_with_one_line() -> None:
    with pytest.raises(SystemExit, match="robots must be a comma list"):
        main(["robots=hovercraft"])
    with pytest.raises(SystemExit, match="unknown argument 'speed=3'; valid: robots="):
        main(["speed=3"])
