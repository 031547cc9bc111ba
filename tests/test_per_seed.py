"""Per-seed tables (semdp.reporting.per_seed): the committed reference table rebuilt from its
kept runs, and hand-computed cells on a synthetic sweep."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from semdp.paths import REFERENCE_DIR
from semdp.reporting.per_seed import main, per_seed_table
from semdp.reporting.runs import load_runs

#: Table 3.1's baselines (with their policies) and the earlier runs it replaced.
FOLDERS = ["semdp_push_8e6_policies", "archive/semdp_push_8e6_seeds"]
#: The command of the folders' COMMAND.md.
ARGUMENTS = ["--title", "Table 3.1 baselines at 8e6 env steps: per seed",
             "--order", "CPO,PPO Lag,TRPO Lag", "--late", "0.1"]


@pytest.mark.parametrize("folder", FOLDERS)
def test_the_committed_per_seed_table_is_rebuilt_from_the_kept_runs(tmp_path: Path,
                                                                    folder: str) -> None:
    out = tmp_path / "per_seed.md"
    main([str(REFERENCE_DIR / folder / "runs"), *ARGUMENTS, "--out", str(out)])
    assert out.read_text() == (REFERENCE_DIR / folder / "per_seed.md").read_text()
    assert "27 runs (3 methods x 3 envs, seeds 0, 1, 2)" in out.read_text()


def _run(path: Path, label: str, seed: int, eval_return: float, eval_cost: float,
         train: tuple[float, float], status: str = "completed") -> None:
    """A run of 10 epochs whose training episodes score ``train`` in the last epoch only."""
    path.mkdir(parents=True)
    with (path / "progress.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["epoch", "env_steps", "ep_return", "ep_cost"])
        for epoch in range(1, 11):
            ret, cost = train if epoch == 10 else (-100.0, 100.0)
            writer.writerow([epoch, 1000 * epoch, ret, cost])
    (path / "metrics.json").write_text(json.dumps({
        "status": status, "label": label, "env": "push1", "seed": seed,
        "eval": {"return_mean": eval_return, "cost_mean": eval_cost},
    }))


def test_cells_are_each_seeds_value_then_mean_and_standard_error(tmp_path: Path) -> None:
    # A: seeds 0-2, returns 1, 2, 6 (mean 3, SE sqrt(7/3)); B: seeds 0 and 2 only, seed 1 failed.
    for seed, ret in enumerate((1.0, 2.0, 6.0)):
        _run(tmp_path / f"a{seed}", "A", seed, ret, 0.5 * seed, (10.0 + seed, 1.0))
    _run(tmp_path / "b0", "B", 0, 4.0, 8.0, (3.0, 2.0))
    _run(tmp_path / "b1", "B", 1, 9.0, 9.0, (9.0, 9.0), status="failed")
    _run(tmp_path / "b2", "B", 2, 6.0, 4.0, (5.0, 4.0))
    text = per_seed_table(load_runs(tmp_path), "T", late=0.1, order=["B"])
    lines = text.splitlines()
    assert lines[0] == "# T"
    eval_rows = lines[lines.index("## Final evaluation") + 4:]
    se = math.sqrt(7.0 / 3.0)
    assert eval_rows[:4] == [
        "| push1 | reward | B | 4.00 | – | 6.00 | 5.00 ± 1.00 (2) |",
        f"| push1 | reward | A | 1.00 | 2.00 | 6.00 | 3.00 ± {se:.2f} (3) |",
        "| push1 | cost | B | 8.00 | – | 4.00 | 6.00 ± 2.00 (2) |",
        "| push1 | cost | A | 0.00 | 0.50 | 1.00 | 0.50 ± 0.29 (3) |",
    ]
    late_rows = lines[lines.index("## Training episodes, last 10% of the epochs") + 4:]
    assert late_rows[:2] == [  # the last epoch only: 10 % of 10 epochs
        "| push1 | reward | B | 3.00 | – | 5.00 | 4.00 ± 1.00 (2) |",
        "| push1 | reward | A | 10.00 | 11.00 | 12.00 | 11.00 ± 0.58 (3) |",
    ]


def test_two_runs_of_one_cell_and_no_usable_run_are_errors(tmp_path: Path) -> None:
    _run(tmp_path / "x", "A", 0, 1.0, 0.0, (1.0, 0.0))
    _run(tmp_path / "y", "A", 0, 2.0, 0.0, (1.0, 0.0))
    with pytest.raises(ValueError, match="two runs of A on push1 with seed 0"):
        per_seed_table(load_runs(tmp_path), "T")
    with pytest.raises(ValueError, match="no run completed"):
        per_seed_table([], "T")
    with pytest.raises(ValueError, match="late"):
        per_seed_table(load_runs(tmp_path), "T", late=0.0)
