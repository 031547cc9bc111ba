"""The policy zoo (outputs/reference/zoo.yaml): every entry evaluates, and re-evaluating an
entry's recorded episodes gives their numbers exactly (deterministic evaluation)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from semdp.evaluation.errors import EvalError
from semdp.evaluation.run import check_run_dir, evaluate_run
from semdp.evaluation.zoo import INDEX, entries, resolve

ZOO = entries()
#: One entry per method, robot and task (names ``<method>_<robot>_<task>_s<seed>``): a table
#: value reproduced.
CHECKED = sorted({tuple(name.split("_")[:3]): name for name in sorted(ZOO)}.values())


def test_the_zoo_has_entries_and_each_holds_a_policy_and_its_evaluation() -> None:
    assert ZOO, f"no entries in {INDEX}"
    for name, run_dir in ZOO.items():
        check_run_dir(run_dir)
        assert (run_dir / "policy.pt").is_file(), name
        recorded = json.loads((run_dir / "eval.json").read_text())
        assert recorded["eval"]["episodes"] == len(recorded["episodes"]) == 50, name


def test_every_entry_was_evaluated_with_the_thesis_protocol() -> None:
    """Sec. 3.5: 50 episodes with the mean action; seeds 10000 + i (+ the run's seed where the
    evaluation offsets them), no evaluation variant, and an override only if it restates that."""
    for name, run_dir in ZOO.items():
        recorded = json.loads((run_dir / "eval.json").read_text())
        settings = recorded["settings"]
        assert settings["actions"] == "mean" and settings.get("variant") is None, name
        assert settings["seeds"][1:] == [s + 1 for s in settings["seeds"][:-1]], name
        assert settings["seeds"][0] - 10000 in (0, recorded["seed"]), name
        assert set(recorded.get("arguments", [])) <= {"actions=mean"}, name


def test_an_unknown_name_lists_the_known_ones() -> None:
    with pytest.raises(EvalError, match=r"no zoo entry 'nope'; known: .*semdp_point_push1_s0"):
        resolve("zoo:nope")
    assert resolve("some/run") == (Path("some/run"), None)


@pytest.mark.parametrize("name", CHECKED)
def test_a_zoo_entry_reproduces_its_recorded_episodes(name: str, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    recorded = json.loads((ZOO[name] / "eval.json").read_text())
    seeds = recorded["settings"]["seeds"][:2]
    monkeypatch.setattr("semdp.evaluation.zoo.REPO_ROOT", tmp_path)  # results go there
    out_dir, metrics = evaluate_run(f"zoo:{name}", [f"seeds=[{seeds[0]},{seeds[1]}]"])
    assert out_dir.is_relative_to(tmp_path / "outputs" / "eval" / name)
    for again, before in zip(metrics["episodes"], recorded["episodes"][:2], strict=True):
        assert (again["return"], again["cost"]) == (before["return"], before["cost"])


def test_the_zoo_table_is_rebuilt_from_the_committed_files() -> None:
    from semdp.reporting.zoo_table import entry_rows, zoo_table

    committed = INDEX.parent / "zoo.md"
    assert committed.read_text() == zoo_table(entry_rows())


def test_the_zoo_table_names_the_task_a_policy_was_trained_on() -> None:
    """``env=semdp_car_push1 env.task=Button1`` trained on CarButton1, whatever the env option's
    name (the config's gymnasium id says so)."""
    from semdp.reporting.zoo_table import entry_rows

    envs = {row["name"]: row["env"] for row in entry_rows()}
    assert envs["semdp_car_button1_s0"] == "CarButton1"
    assert envs["semdp_car_push1_s0"] == "CarPush1"
    assert envs["sg-ppolag_point_goal1_s0"] == "PointGoal1"


def test_the_zoo_table_averages_a_methods_seeds_per_env(tmp_path: Path) -> None:
    from semdp.reporting.zoo_table import entry_rows, zoo_table

    for name, label, seed, ret in (("r0", "Ours", 0, 4.0), ("r1", "Ours", 1, 6.0),
                                   ("r2", "PPO Lag", 0, 1.0)):
        run = tmp_path / name
        run.mkdir()
        summary = {"return_mean": ret, "return_std": 1.0, "cost_mean": 0.0, "episodes": 50,
                   "episodes_with_cost": 0, "plans": 5000, "plan_fallbacks": 0}
        (run / "eval.json").write_text(json.dumps(
            {"label": f"{label} [eval]", "env": "semdp_car_push1", "seed": seed,
             "env_steps": 200000, "eval": summary}))
    (tmp_path / "zoo.yaml").write_text("a: r0\nb: r1\nc: r2\n")
    table = zoo_table(entry_rows(tmp_path / "zoo.yaml"))
    # mean 5, sample standard deviation sqrt(2), standard error sqrt(2) / sqrt(2) = 1
    # the env option's name in the thesis' form (semdp/reporting/names.py)
    assert "| Ours | CarPush1 | 200,000 | 2 | 5.00 ± 1.00 | 0.00 ± 0.00 |" in table
    assert "| PPO Lag | CarPush1 | 200,000 | 1 | 1.00 ± – | 0.00 ± – |" in table
    assert ("| `a` | Ours | CarPush1 | 0 | 200,000 | 4.000 ± 1.000 | 0.000 | 0 / 50 "
            "| 0 / 5000 |") in table
