"""`semdp-toy` Hydra app: config composition, outputs in the run directory, presets."""

from __future__ import annotations

import inspect
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from PIL import Image

from semdp.cli.toy import FIGURE_NAME, SUMMARY_NAME, format_table, run
from semdp.paths import CONF_DIR
from solvers.self_paced_lagrangian import GLOBAL_OPTIMUM_VALUE, SelfPacedLagrangianToy

PI = math.pi
FAST = ["solver.multistart_points=9"]


def _compose(overrides: list[str], return_hydra_config: bool = False):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose("toy", overrides=overrides, return_hydra_config=return_hydra_config)


def test_toy_config_keys_equal_constructor_arguments() -> None:
    cfg = _compose([])
    keys = set(cfg.solver) - {"_target_"}
    parameters = set(inspect.signature(SelfPacedLagrangianToy).parameters)
    assert keys == parameters
    assert cfg.solver._target_ == "solvers.self_paced_lagrangian.SelfPacedLagrangianToy"


def test_toy_config_defaults_match_constructor_defaults() -> None:
    cfg = _compose([])
    for name, parameter in inspect.signature(SelfPacedLagrangianToy).parameters.items():
        configured = cfg.solver[name]
        default = parameter.default
        if isinstance(default, tuple):
            assert list(configured) == pytest.approx(list(default), abs=1e-12), name
        else:
            assert configured == default, name


def test_toy_run_writes_figure_and_summary(tmp_path: Path) -> None:
    summary = run(_compose(["x0=-5.0", *FAST]), tmp_path)
    image = Image.open(tmp_path / FIGURE_NAME)
    assert image.size[0] > 800 and image.size[1] > 600
    on_disk = json.loads((tmp_path / SUMMARY_NAME).read_text())
    assert on_disk["x0"] == -5.0
    assert on_disk["f_star"] == pytest.approx(GLOBAL_OPTIMUM_VALUE)
    methods = on_disk["methods"]
    assert set(methods) == {
        "lagrangian",
        "self_paced",
        "self_paced_literal",
        "ipopt_direct",
        "ipopt_homotopy",
        "ipopt_multistart",
    }
    required = {"x", "f", "c", "lagrange_multiplier", "iterations", "reached_global_optimum"}
    for row in methods.values():
        assert required <= set(row)
    # x0 = -5 lies in the wrong component: plain is trapped, the self-paced variants are not.
    assert methods["self_paced"]["reached_global_optimum"] is True
    assert methods["ipopt_homotopy"]["reached_global_optimum"] is True
    assert methods["ipopt_multistart"]["reached_global_optimum"] is True
    assert methods["lagrangian"]["reached_global_optimum"] is False
    assert methods["ipopt_direct"]["x"] == pytest.approx(-3 * PI / 2, abs=1e-6)
    assert summary["methods"] == methods
    table = format_table(summary)
    assert "self_paced" in table and "ipopt_homotopy" in table


def test_toy_run_rejects_non_numeric_start(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="x0"):
        run(_compose(["x0=abc", *FAST]), tmp_path)
    assert not (tmp_path / SUMMARY_NAME).exists()


def test_toy_cli_reports_bad_start_in_one_line(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "semdp.cli.toy", "x0=abc", f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0
    assert "semdp-toy: x0 must be a finite real number, got 'abc'" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("solver.num_thresholds=-1",
         "semdp-toy: solver.num_thresholds must be an integer >= 0, got -1"),
        ("solver.lr_x=0", "semdp-toy: solver.lr_x must be > 0, got 0"),
    ],
)
def test_toy_cli_reports_bad_solver_setting_in_one_line(tmp_path: Path, override, message) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "semdp.cli.toy", override, f"hydra.run.dir={tmp_path}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0
    assert done.stderr.strip() == message
    assert not (tmp_path / SUMMARY_NAME).exists()


def test_toy_experiment_preset_sweeps_20_starts_over_three_intervals() -> None:
    cfg = _compose(["experiment=toy", "budget=ci"], return_hydra_config=True)
    starts = [float(v) for v in str(cfg.hydra.sweeper.params.x0).split(",")]
    assert len(starts) >= 20
    intervals = [(-5 * PI / 2, -3 * PI / 2), (3 * PI / 2 + 0.1, 5 * PI / 2), (-PI / 2, PI / 2)]
    assert all(any(low <= x <= high for low, high in intervals) for x in starts)
    assert all(sum(low <= x <= high for x in starts) >= 6 for low, high in intervals)
    assert cfg.hydra.launcher._target_.endswith("JoblibLauncher")
    assert cfg.hydra.launcher.n_jobs == 2


@pytest.mark.slow
def test_toy_multirun_with_joblib_launcher(tmp_path: Path) -> None:
    sweep_dir = tmp_path / "sweep"
    command = [
        sys.executable,
        "-m",
        "semdp.cli.toy",
        "-m",
        "x0=-5,0.3",
        f"hydra.sweep.dir={sweep_dir}",
        *FAST,
    ]
    subprocess.run(command, check=True, cwd=tmp_path, capture_output=True, timeout=300)
    summaries = sorted(sweep_dir.glob(f"*/{SUMMARY_NAME}"))
    assert len(summaries) == 2
    for path in summaries:
        assert (path.parent / FIGURE_NAME).is_file()
        assert json.loads(path.read_text())["methods"]["self_paced"]["reached_global_optimum"]
