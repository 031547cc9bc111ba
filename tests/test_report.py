"""`semdp-report` on synthetic sweeps: hand-computed mean ± standard error as the oracle."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from semdp.cli.report import main
from semdp.reporting.names import algorithm_name, env_name
from semdp.reporting.plots import aggregate_curves, smooth
from semdp.reporting.runs import find_run_dirs, load_run, load_runs, mean_and_standard_error
from semdp.reporting.tables import TABLE_NAME, build_table, format_cell, write_report

HEADER = [
    "epoch", "env_steps", "wall_time_s", "fps", "ep_return", "ep_cost", "ep_length",
    "lagrange_multiplier", "cost_threshold", "eval_return", "eval_cost",
]  # fmt: skip


def _write_run(
    path: Path,
    *,
    algo: str,
    env: str,
    seed: int,
    eval_return: float | None = None,
    eval_cost: float | None = None,
    status: str = "completed",
    rows: int = 30,
    offset: float = 0.0,
    metrics: bool = True,
    extra: dict[str, Any] | None = None,
) -> Path:
    path.mkdir(parents=True)
    (path / ".hydra").mkdir()
    with (path / "progress.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(HEADER)
        for epoch in range(1, rows + 1):
            steps = 1000 * epoch
            writer.writerow(
                [epoch, steps, epoch * 0.1, 1e4, 0.001 * steps + offset, 5.0 + offset, 1000,
                 0.1, 25.0, "", ""]
            )  # fmt: skip
    if metrics:
        content: dict[str, Any] = {
            "status": status,
            "error": "RuntimeError: boom" if status == "failed" else None,
            "algo": algo,
            "env": env,
            "seed": seed,
            "env_steps": 1000 * rows,
            "wall_time_s": 1.0,
            "eval": None
            if eval_return is None
            else {
                "episodes": 50,
                "return_mean": eval_return,
                "return_std": 1.0,
                "cost_mean": eval_cost,
                "cost_std": 0.0,
                "success_rate": None,
            },
        }
        content.update(extra or {})
        (path / "metrics.json").write_text(json.dumps(content))
    return path


@pytest.fixture
def sweep(tmp_path: Path) -> Path:
    root = tmp_path / "sweep"
    # env push1: semdp returns 5, 6, 7 (mean 6, SE 1/sqrt(3)), costs 0; ppo_lag returns 1, 3
    # (mean 2, SE 1), costs 4, 8 (mean 6, SE 2).
    for seed, ret in enumerate((5.0, 6.0, 7.0)):
        _write_run(root / f"{seed}", algo="semdp", env="push1", seed=seed, eval_return=ret,
                   eval_cost=0.0, offset=float(seed))  # fmt: skip
    for seed, (ret, cost) in enumerate(((1.0, 4.0), (3.0, 8.0))):
        _write_run(root / f"{3 + seed}", algo="ppo_lag", env="push1", seed=seed, eval_return=ret,
                   eval_cost=cost)  # fmt: skip
    # env goal1: one seed of a labelled variant (label beats algo).
    _write_run(root / "5", algo="semdp", env="goal1", seed=0, eval_return=2.5, eval_cost=0.5,
               extra={"label": "Ours w/ gt"})  # fmt: skip
    # incomplete runs of all kinds
    _write_run(root / "6", algo="ppo_lag", env="push1", seed=2, status="failed", rows=3)
    _write_run(root / "7", algo="ppo_lag", env="push1", seed=3, status="running", rows=5)
    _write_run(root / "8", algo="cpo", env="push1", seed=0, metrics=False, rows=4)
    _write_run(root / "9", algo="cpo", env="push1", seed=1, eval_return=1.0, eval_cost=1.0,
               rows=0)  # fmt: skip
    (root / "10" / ".hydra").mkdir(parents=True)  # a job that never wrote anything
    return root


def test_mean_and_standard_error_matches_hand_computation() -> None:
    mean, error = mean_and_standard_error([5.0, 6.0, 7.0])
    assert mean == 6.0 and error == pytest.approx(1 / math.sqrt(3))
    assert mean_and_standard_error([1.0, 3.0]) == (2.0, pytest.approx(1.0))
    single = mean_and_standard_error([4.0])
    assert single[0] == 4.0 and math.isnan(single[1])
    with pytest.raises(ValueError):
        mean_and_standard_error([])


def test_format_cell_marks_missing_seeds() -> None:
    assert format_cell([5.0, 6.0, 7.0], max_seeds=3) == "6.00 ± 0.58"
    assert format_cell([1.0, 3.0], max_seeds=3) == "2.00 ± 1.00 (n=2)"
    assert format_cell([4.0], max_seeds=1) == "4.00 ± –"
    assert format_cell([], max_seeds=3) == "–"


def test_find_run_dirs_includes_incomplete_and_never_started(sweep: Path) -> None:
    found = [path.name for path in find_run_dirs(sweep)]
    assert sorted(found, key=int) == [str(i) for i in range(11)]


def test_load_run_reports_each_kind_of_incomplete_run(sweep: Path) -> None:
    failed = load_run(sweep / "6")
    assert failed.status == "failed" and failed.error == "RuntimeError: boom"
    assert not failed.has_final_eval and "status failed" in failed.problems
    assert load_run(sweep / "7").problems[0] == "status running"
    no_metrics = load_run(sweep / "8")
    assert no_metrics.status == "no metrics.json" and no_metrics.curves["env_steps"].size == 4
    empty_csv = load_run(sweep / "9")
    assert empty_csv.has_final_eval and "empty progress.csv" in empty_csv.problems
    assert load_run(sweep / "5").label == "Ours w/ gt"
    never = load_run(sweep / "10")
    assert set(never.problems) == {"no metrics.json", "no progress.csv"}


def test_table_has_table_3_1_layout_with_mean_and_standard_error(sweep: Path) -> None:
    runs = load_runs(sweep)
    table = build_table(runs, sweep)
    lines = table.splitlines()
    header = next(line for line in lines if line.startswith("| env |"))
    columns = [c.strip() for c in header.strip("|").split("|")]
    # Hydra choice names read as the thesis writes them; preset labels are kept
    assert columns == ["env", "metric", "CPO", "Ours w/ gt", "PPO-Lag", "semdp"]
    rows = {
        tuple(c.strip() for c in line.strip("|").split("|")[:2]): [
            c.strip() for c in line.strip("|").split("|")[2:]
        ]
        for line in lines
        if line.startswith("| push1") or line.startswith("| goal1")
    }
    assert rows[("push1", "reward")] == ["1.00 ± – (n=1)", "–", "2.00 ± 1.00 (n=2)", "6.00 ± 0.58"]
    assert rows[("push1", "cost")] == ["1.00 ± – (n=1)", "–", "6.00 ± 2.00 (n=2)", "0.00 ± 0.00"]
    assert set(rows) == {(env, m) for env in ("push1", "goal1") for m in ("reward", "cost")}
    assert rows[("goal1", "reward")][1] == "2.50 ± –"
    # every incomplete run is named with its reason
    for name, reason in [("6", "status failed"), ("7", "status running"),
                         ("8", "no metrics.json"), ("9", "empty progress.csv"),
                         ("10", "no metrics.json")]:  # fmt: skip
        line = next(line for line in lines if line.startswith(f"- `{name}`"))
        assert reason in line
    assert "RuntimeError: boom" in table


def test_smooth_adapts_window_and_preserves_quadratics() -> None:
    x = np.arange(40, dtype=float)
    quadratic = 0.5 * x**2 - x + 3
    np.testing.assert_allclose(smooth(quadratic), quadratic, atol=1e-8)
    short = np.array([1.0, 5.0, 2.0])
    np.testing.assert_array_equal(smooth(short), short)  # too short for polyorder 2: unchanged
    noisy = np.tile([0.0, 1.0], 20)
    assert smooth(noisy).std() < noisy.std() / 3
    # 15 epochs: window 5, not one parabola through the whole run; never outside the data range
    spike = np.zeros(15)
    spike[7] = 10.0
    smoothed = smooth(spike)
    assert smoothed.min() >= 0.0 and smoothed.max() <= 10.0
    np.testing.assert_array_equal(smoothed[:3], 0.0)  # outside the window of the spike


def test_aggregate_curves_mean_and_standard_error_oracle() -> None:
    steps = np.linspace(0.0, 100.0, 51)
    grid, mean, error = aggregate_curves([(steps, steps), (steps, steps + 2.0)], points=11)
    np.testing.assert_allclose(grid, np.linspace(0.0, 100.0, 11))
    np.testing.assert_allclose(mean, grid + 1.0, atol=1e-8)
    np.testing.assert_allclose(error, 1.0, atol=1e-8)  # std([a, a+2], ddof=1)/sqrt(2) = 1


def test_aggregate_curves_uses_only_seeds_covering_each_step() -> None:
    long_steps = np.linspace(0.0, 100.0, 51)
    short_steps = np.linspace(0.0, 50.0, 26)
    grid, mean, error = aggregate_curves(
        [(long_steps, np.full(51, 4.0)), (short_steps, np.full(26, 2.0))], points=11
    )
    beyond = grid > 50.0
    np.testing.assert_allclose(mean[beyond], 4.0)
    np.testing.assert_allclose(error[beyond], 0.0)
    np.testing.assert_allclose(mean[~beyond], 3.0)


def test_write_report_writes_table_curves_and_tradeoff(tmp_path: Path) -> None:
    root = tmp_path / "tradeoff_sweep"
    for seed in range(2):
        points = [
            {"clearance": eps, "return_mean": 5.0 - eps + seed, "cost_mean": 1.0 - eps}
            for eps in (0.1, 0.3, 0.5)
        ]
        _write_run(root / f"ours_{seed}", algo="semdp", env="point_push1", seed=seed,
                   eval_return=5.0, eval_cost=0.0, extra={"tradeoff": points})  # fmt: skip
        _write_run(root / f"cpo_{seed}", algo="cpo", env="point_push1", seed=seed,
                   eval_return=3.0, eval_cost=2.0)  # fmt: skip
    written = write_report(root, tmp_path / "report")
    names = sorted(path.name for path in written)
    assert names == ["curves_PointPush1.png", "table.md", "tradeoff_PointPush1.png"]
    for path in written:
        if path.suffix == ".png":
            assert Image.open(path).size[0] > 500


def test_cli_writes_default_out_dir_and_tolerates_incomplete_runs(
    sweep: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main([str(sweep)])
    out = sweep / "report"
    assert (out / TABLE_NAME).is_file()
    assert (out / "curves_push1.png").is_file() and (out / "curves_goal1.png").is_file()
    assert not list(out.glob("tradeoff_*"))  # no run carries trade-off points
    printed = capsys.readouterr().out
    assert "Failed or unfinished runs" in printed
    main([str(sweep)])  # a second run ignores its own report directory
    assert "Runs found: 11" in (out / TABLE_NAME).read_text()


def test_cli_order_puts_named_methods_first(sweep: Path, tmp_path: Path) -> None:
    main([str(sweep), "--out", str(tmp_path / "ordered"), "--order", "semdp, ppo_lag,absent"])
    header = next(
        line
        for line in (tmp_path / "ordered" / TABLE_NAME).read_text().splitlines()
        if line.startswith("| env |")
    )
    assert [c.strip() for c in header.strip("|").split("|")][2:] == [
        "semdp", "PPO-Lag", "CPO", "Ours w/ gt"
    ]  # fmt: skip


def test_cli_without_runs_exits_with_message(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="no run directories"):
        main([str(tmp_path)])
    with pytest.raises(SystemExit, match="not a directory"):
        main([str(tmp_path / "missing")])


def test_training_curves_skip_failed_runs(tmp_path: Path) -> None:
    from semdp.reporting.plots import plot_training_curves

    failed = load_run(_write_run(tmp_path / "f", algo="ppo", env="e", seed=0, status="failed"))
    running = load_run(_write_run(tmp_path / "r", algo="ppo", env="e", seed=1, status="running"))
    assert not plot_training_curves([failed], "e", tmp_path / "failed.png")
    assert not (tmp_path / "failed.png").exists()
    assert plot_training_curves([failed, running], "e", tmp_path / "running.png")



def test_curve_legend_counts_seeds_in_words() -> None:
    from semdp.reporting.plots import _legend

    assert _legend("CPO", 1) == "CPO (1 seed)"
    assert _legend("Ours", 3) == "Ours (3 seeds)"

def test_semdp_curves_are_put_on_low_level_env_steps(tmp_path: Path) -> None:
    """A SEMDP run logs high-level steps; the report multiplies them by k (10 here)."""
    finished = load_run(
        _write_run(tmp_path / "done", algo="sac", env="PointPush1", seed=0, rows=3,
                   extra={"semdp": {"k": 10}})
    )  # fmt: skip
    assert finished.curves["env_steps"].tolist() == [10_000.0, 20_000.0, 30_000.0]
    unfinished = _write_run(tmp_path / "running", algo="sac", env="PointPush1", seed=1, rows=2,
                            metrics=False)  # fmt: skip
    (unfinished / "config.yaml").write_text(
        "label: Ours\nenv:\n  wrapper:\n    _target_: semdp.embedded.wrapper.SafetyEmbeddedEnv\n"
        "    k: 5\n"
    )
    assert load_run(unfinished).curves["env_steps"].tolist() == [5_000.0, 10_000.0]
    plain = load_run(_write_run(tmp_path / "ppo", algo="ppo", env="PointPush1", seed=0, rows=2))
    assert plain.curves["env_steps"].tolist() == [1_000.0, 2_000.0]


@pytest.mark.parametrize(
    ("raw", "algo", "env"),
    [("ppo_lag", "PPO-Lag", None), ("sp_ppo_lag", "SP-PPO-Lag", None), ("Ours", "Ours", None),
     ("point_goal1", None, "PointGoal1"), ("car_button2", None, "CarButton2"),
     ("drive_circle_v4.0", None, "Circle 4 m/s"), ("PointPush1", None, "PointPush1"),
     ("semdp_mass_push2", None, "MassPush2")],
)
def test_report_names_read_as_the_thesis_writes_them(raw: str, algo: str | None,
                                                     env: str | None) -> None:
    if algo is not None:
        assert algorithm_name(raw) == algo
    if env is not None:
        assert env_name(raw) == env


def test_semdp_curves_start_after_the_followers_training_steps(tmp_path: Path) -> None:
    """Fig. 3.3: a SEMDP run's curve is on env steps (k per logged step) plus the follower's
    training steps recorded as ``env.pretrain_steps``."""
    run_dir = tmp_path / "ours"
    _write_run(run_dir, algo="semdp", env="point_push1", seed=0, eval_return=1.0, eval_cost=0.0,
               extra={"semdp": {"k": 10}})
    (run_dir / "config.yaml").write_text("env:\n  pretrain_steps: 60000\n  wrapper: null\n")
    steps = load_run(run_dir).curves["env_steps"]
    logged = np.array([float(r["env_steps"]) for r in csv.DictReader(
        (run_dir / "progress.csv").open())])
    np.testing.assert_allclose(steps, logged * 10 + 60000)


def test_compare_adds_differences_with_their_standard_errors(sweep: Path) -> None:
    # push1: semdp 6 ± 1/sqrt(3), PPO-Lag 2 ± 1 -> +4 ± sqrt(1/3 + 1) = 1.1547, +3.5 SE;
    # cost 0 ± 0 vs 6 ± 2 -> -6 ± 2, -3.0 SE; goal1 has no PPO-Lag run.
    table = build_table(load_runs(sweep), sweep, compare=("semdp", "ppo_lag"))
    lines = table.splitlines()
    assert "## semdp − PPO-Lag (final evaluation)" in lines
    row = next(line for line in lines if line.startswith("| push1 |") and "±" in line
               and line.count("|") == 6)
    assert [c.strip() for c in row.strip("|").split("|")] == \
        ["push1", "+4.00 ± 1.15", "+3.5", "-6.00 ± 2.00", "-3.0"]
    goal = next(line for line in lines if line.startswith("| goal1 |") and line.count("|") == 6)
    assert goal.count("–") == 4
    with pytest.raises(ValueError, match="no method 'TRPO-Lag'"):
        build_table(load_runs(sweep), sweep, compare=("semdp", "trpo_lag"))


def test_cli_compare_rejects_a_malformed_pair(sweep: Path, tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="two method labels"):
        main([str(sweep), "--out", str(tmp_path / "r"), "--compare", "semdp"])


def test_late_training_table_averages_the_last_epochs(sweep: Path) -> None:
    # progress rows: ep_return = epoch + offset, ep_cost = 5 + offset, 30 epochs; the last
    # 10 % are epochs 28-30 (mean 29 + offset). semdp offsets 0, 1, 2 -> 29, 30, 31.
    table = build_table(load_runs(sweep), sweep, late=0.1, compare=("semdp", "ppo_lag"))
    section = table.split("## Training episodes, last 10% of the epochs")[1]
    rows = {tuple(c.strip() for c in line.strip("|").split("|")[:2]):
            [c.strip() for c in line.strip("|").split("|")[2:]]
            for line in section.splitlines() if line.startswith("| push1 |")
            and line.count("|") == 7}
    assert rows[("push1", "reward")][2:] == ["29.00 ± 0.00 (n=2)", "30.00 ± 0.58"]
    assert rows[("push1", "cost")][2:] == ["5.00 ± 0.00 (n=2)", "6.00 ± 0.58"]
    assert "## semdp − PPO-Lag (training episodes)" in section
    with pytest.raises(ValueError, match="late must be in"):
        build_table(load_runs(sweep), sweep, late=1.5)


def test_training_table_at_a_step_mark_is_that_of_runs_stopped_there(sweep: Path) -> None:
    # Up to 20,000 env steps: epochs 1-20, the last 10 % are epochs 19-20 (ep_return mean
    # 19.5 + offset): semdp 19.5, 20.5, 21.5 -> 20.50 ± 0.58; PPO-Lag 19.50 (2 runs). No run
    # reached 40,000 steps: every cell of that table is empty.
    table = build_table(load_runs(sweep), sweep, at=(20000.0, 40000.0),
                        compare=("semdp", "ppo_lag"))
    section = table.split("## Training episodes at 20000 env steps")[1].split("## Training")[0]
    rows = {tuple(c.strip() for c in line.strip("|").split("|")[:2]):
            [c.strip() for c in line.strip("|").split("|")[2:]]
            for line in section.splitlines() if line.startswith("| push1 |")
            and line.count("|") == 7}
    assert rows[("push1", "reward")][2:] == ["19.50 ± 0.00 (n=2)", "20.50 ± 0.58"]
    assert "## semdp − PPO-Lag (training episodes at 20000 env steps)" in section
    unreached = table.split("## Training episodes at 40000 env steps")[1]
    assert all(cell.strip() == "–" for line in unreached.splitlines()
               if line.startswith("| push1 |") and line.count("|") == 7
               for cell in line.strip("|").split("|")[2:])
    with pytest.raises(ValueError, match="marks must be > 0"):
        build_table(load_runs(sweep), sweep, at=(0.0,))


def test_cli_at_rejects_a_mark_that_is_not_a_number(sweep: Path, tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="env-step numbers"):
        main([str(sweep), "--out", str(tmp_path / "r"), "--at", "150k"])


def test_several_sweeps_are_reported_together_each_run_once(tmp_path: Path) -> None:
    # One sweep per seed (as long runs are launched): semdp returns 5 and 6 in the first, 7 in
    # the second -> 6.00 ± 0.58 over 3 seeds; a sweep given twice and a run dir inside a given
    # sweep add nothing.
    first, second = tmp_path / "s01", tmp_path / "s2"
    for seed, ret in enumerate((5.0, 6.0)):
        _write_run(first / f"{seed}", algo="semdp", env="push1", seed=seed, eval_return=ret,
                   eval_cost=0.0)  # fmt: skip
    _write_run(second / "0", algo="semdp", env="push1", seed=2, eval_return=7.0, eval_cost=0.0)
    write_report([first, second, first, first / "0"], tmp_path / "out")
    table = (tmp_path / "out" / TABLE_NAME).read_text()
    assert "| push1 | reward | 6.00 ± 0.58 |" in table
    assert "Runs found: 3; with a final evaluation: 3." in table
    main([str(first), str(second), "--out", str(tmp_path / "cli")])
    assert (tmp_path / "cli" / TABLE_NAME).read_text().replace(str(tmp_path / "cli"), "") == \
        table.replace(str(tmp_path / "out"), "")
    with pytest.raises(SystemExit, match="not a directory"):
        main([str(first), str(tmp_path / "nope"), "--out", str(tmp_path / "bad")])


def test_cost_limit_is_read_from_config_and_drawn_only_when_shared(tmp_path: Path) -> None:
    from semdp.reporting.plots import shared_cost_limit

    runs = []
    for i, limit in enumerate(("25.0", "25", None)):
        path = _write_run(tmp_path / str(i), algo="ppo_lag", env="goal1", seed=i,
                          eval_return=1.0, eval_cost=1.0)
        if limit is not None:
            (path / "config.yaml").write_text(f"algo:\n  cost_limit: 3.0\ncost_limit: {limit}\n")
        runs.append(load_run(path))
    assert [run.cost_limit for run in runs] == [25.0, 25.0, None]
    assert shared_cost_limit(runs[:2]) == 25.0
    assert shared_cost_limit(runs) is None  # one run's limit unknown: no line
    # SAC ("Ours") beside the constrained runs: its config's cost_limit is not a limit it was
    # trained with (its algo block has none), so it neither draws nor blocks the line.
    sac = _write_run(tmp_path / "sac", algo="sac", env="goal1", seed=0, eval_return=1.0,
                     eval_cost=0.0)
    (sac / "config.yaml").write_text("algo:\n  lr: 0.001\n  nested:\n    x: 1\n"
                                     "cost_limit: 25.0\nseed: 0\n")
    ours = load_run(sac)
    assert ours.cost_limit == 25.0 and ours.unconstrained and not runs[0].unconstrained
    assert shared_cost_limit([*runs[:2], ours]) == 25.0
    assert shared_cost_limit([ours]) is None


def test_a_run_is_named_by_the_task_it_stepped(tmp_path: Path) -> None:
    """``env=semdp_point_push1 env.task=Button1`` records the option's name; the table names
    the task in the config's env id."""
    from semdp.reporting.names import env_name_from_id
    from semdp.reporting.runs import load_run

    assert env_name_from_id("sims/SafetyPointButton1-v0") == "PointButton1"
    assert env_name_from_id("sims/DriveCircle-v0") is None
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text(json.dumps(
        {"status": "completed", "algo": "sac", "env": "semdp_point_push1", "seed": 0,
         "label": "Ours", "eval": {"return_mean": 1.0, "cost_mean": 0.0}}))
    (run / "config.yaml").write_text(
        "env:\n  task: Button1\n  id: sims/SafetyPointButton1-v0\nseed: 0\n")
    assert load_run(run).env == "PointButton1"
    (run / "config.yaml").write_text("seed: 0\n")
    assert load_run(run).env == "PointPush1"
