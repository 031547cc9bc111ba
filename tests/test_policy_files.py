"""Policy files are data (semdp/common/policy_files.py): a planted ``policy.pt``, follower weight
file and zoo entry whose pickle would create a file are refused with one line and the file is
never created; empty, truncated, foreign and misfitting files get one line naming them; every
committed policy and follower file loads."""

from __future__ import annotations

import glob
import shutil
from pathlib import Path

import pytest
import torch

from semdp.common.policy_files import PolicyFileError, load_data
from semdp.embedded.follower_weights import load_follower_actor
from semdp.evaluation.errors import EvalError
from semdp.evaluation.run import evaluate_run
from semdp.evaluation.zoo import entries
from semdp.paths import REFERENCE_DIR

ENTRY = "semdp_point_push1_s0"


class _Planted:
    """Unpickling this calls ``open(marker, "w")``: it creates the marker file."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (str(self.marker), "w"))


def _plant(path: Path, marker: Path, like: Path) -> None:
    payload = torch.load(like, weights_only=False)
    payload["planted"] = _Planted(marker)
    torch.save(payload, path)


def _zoo_copy(tmp_path: Path) -> Path:
    run = tmp_path / "zoo" / "run"
    shutil.copytree(entries()[ENTRY], run)
    (tmp_path / "zoo" / "zoo.yaml").write_text(f"{ENTRY}: run\n")
    return run


def test_a_planted_policy_run_dir_and_zoo_entry_are_refused_and_run_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    marker = tmp_path / "pwned"
    run = _zoo_copy(tmp_path)
    _plant(run / "policy.pt", marker, entries()[ENTRY] / "policy.pt")
    with pytest.raises(EvalError) as info:
        evaluate_run(run, ["episodes=1"])  # the run directory
    assert "refused" in str(info.value) and "policy.pt" in str(info.value)
    assert "\n" not in str(info.value)
    monkeypatch.setattr("semdp.evaluation.zoo.INDEX", tmp_path / "zoo" / "zoo.yaml")
    monkeypatch.setattr("semdp.evaluation.zoo.REPO_ROOT", tmp_path)
    with pytest.raises(EvalError, match="refused"):
        evaluate_run(f"zoo:{ENTRY}", ["episodes=1"])  # the zoo entry
    assert not marker.exists()
    assert not list(run.glob("eval_*")) and not (tmp_path / "outputs").exists()


def test_planted_follower_weights_are_refused_and_run_nothing(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    weights = tmp_path / "point.pt"
    _plant(weights, marker, Path(__file__).parents[1] / "semdp/embedded/weights/point.pt")
    with pytest.raises(PolicyFileError, match="refused"):
        load_follower_actor(weights)
    assert not marker.exists()


def test_empty_truncated_and_foreign_files_get_one_line_naming_them(tmp_path: Path) -> None:
    good = (entries()[ENTRY] / "policy.pt").read_bytes()
    cases = {"empty.pt": b"", "truncated.pt": good[: len(good) // 2],
             "text.pt": b"not a torch file\n"}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(PolicyFileError) as info:
            load_data(tmp_path / name, "policy")
        assert str(info.value).startswith(str(tmp_path / name)) and "\n" not in str(info.value)
    torch.save([1, 2, 3], tmp_path / "list.pt")
    with pytest.raises(PolicyFileError, match="holds a mapping, this one a list"):
        load_data(tmp_path / "list.pt", "policy")
    with pytest.raises(PolicyFileError, match="no such policy file"):
        load_data(tmp_path / "missing.pt", "policy")


def test_a_policy_for_another_network_size_gets_one_line(tmp_path: Path) -> None:
    run = _zoo_copy(tmp_path)
    with pytest.raises(EvalError) as info:
        evaluate_run(run, ["episodes=1", "algo.hidden_sizes=[32,32]"])
    assert "does not fit the network" in str(info.value) and "\n" not in str(info.value)
    assert not list(run.glob("eval_*"))


def test_every_committed_policy_and_follower_file_loads_as_data() -> None:
    files = sorted(glob.glob(str(REFERENCE_DIR / "**" / "policy.pt"), recursive=True))
    files += sorted(glob.glob(str(Path(__file__).parents[1] / "semdp/embedded/weights/*.pt")))
    assert len(files) > 100
    for path in files:
        assert isinstance(load_data(path, "policy"), dict)
