"""The zoo outside a checkout (semdp/zoo_data.py, setup.py's build step): the files a wheel
ships are exactly the index and each entry's config, policy, metrics and recorded evaluation,
and ``semdp-eval zoo:<entry>`` from that copy reproduces the recorded episodes.

The slow test builds the wheel itself from a copy of the tracked files and checks what it
holds and its size.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from semdp import zoo_data
from semdp.evaluation.run import evaluate_run
from semdp.paths import REFERENCE_DIR

ROOT = Path(__file__).resolve().parents[1]
ENTRY = "semdp_point_push1_s0"


def test_the_index_reads_as_yaml_does() -> None:
    expected = OmegaConf.to_container(OmegaConf.load(REFERENCE_DIR / "zoo.yaml"))
    assert zoo_data.read_index(REFERENCE_DIR / "zoo.yaml") == expected
    assert len(expected) > 100


def test_a_bad_index_line_is_named(tmp_path: Path) -> None:
    (tmp_path / "zoo.yaml").write_text("# comment\na: b/c\nnot an entry\n")
    with pytest.raises(ValueError, match=r"zoo.yaml:3"):
        zoo_data.read_index(tmp_path / "zoo.yaml")


@pytest.fixture(scope="module")
def copied(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    target = tmp_path_factory.mktemp("wheel") / "semdp" / "zoo"
    return target, zoo_data.copy_zoo(REFERENCE_DIR, target)


def test_the_copy_holds_exactly_the_entries_files(copied: tuple[Path, list[Path]]) -> None:
    target, written = copied
    index = zoo_data.read_index(REFERENCE_DIR / "zoo.yaml")
    expected = {Path("zoo.yaml")}
    for run_dir in index.values():
        for name in zoo_data.ENTRY_FILES:
            if (REFERENCE_DIR / run_dir / name).is_file():
                expected.add(Path(run_dir) / name)
    found = {p.relative_to(target) for p in target.rglob("*") if p.is_file()}
    assert found == expected == {p.relative_to(target) for p in written}
    for run_dir in index.values():
        for name in zoo_data.REQUIRED:
            assert (target / run_dir / name).read_bytes() == (
                REFERENCE_DIR / run_dir / name).read_bytes()
    assert not any(p.name == "progress.csv" for p in target.rglob("*"))


def test_an_entry_without_its_policy_stops_the_copy(tmp_path: Path) -> None:
    (tmp_path / "ref" / "run").mkdir(parents=True)
    (tmp_path / "ref" / "zoo.yaml").write_text("x: run\n")
    (tmp_path / "ref" / "run" / "config.yaml").write_text("a: 1\n")
    with pytest.raises(FileNotFoundError, match=r"policy\.pt"):
        zoo_data.copy_zoo(tmp_path / "ref", tmp_path / "out")


def test_the_checkout_wins_and_the_package_copy_is_the_fallback(tmp_path: Path) -> None:
    assert zoo_data.zoo_root(REFERENCE_DIR) == REFERENCE_DIR
    assert zoo_data.zoo_root(tmp_path) == zoo_data.PACKAGED
    assert zoo_data.PACKAGED == Path(zoo_data.__file__).parent / "zoo"


def test_an_entry_evaluates_from_the_copy_as_recorded(copied: tuple[Path, list[Path]],
                                                       tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    target, _ = copied
    monkeypatch.setattr("semdp.evaluation.zoo.INDEX", target / "zoo.yaml")
    monkeypatch.setattr("semdp.evaluation.zoo.REPO_ROOT", tmp_path)
    run_dir = target / zoo_data.read_index(target / "zoo.yaml")[ENTRY]
    recorded = json.loads((run_dir / "eval.json").read_text())
    seeds = recorded["settings"]["seeds"][:2]
    out_dir, metrics = evaluate_run(f"zoo:{ENTRY}", [f"seeds=[{seeds[0]},{seeds[1]}]"])
    assert out_dir.is_relative_to(tmp_path / "outputs" / "eval" / ENTRY)
    assert metrics["evaluation_of"] == str(run_dir)
    for again, before in zip(metrics["episodes"], recorded["episodes"][:2], strict=True):
        assert (again["return"], again["cost"]) == (before["return"], before["cost"])


@pytest.mark.slow
def test_the_wheel_ships_the_zoo(tmp_path: Path) -> None:
    source = tmp_path / "src"
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                             check=True).stdout.decode().split("\0")
    for name in filter(None, tracked):
        path = ROOT / name
        if path.is_file() and not path.is_symlink():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, source / name)
    os.symlink("../conf", source / "semdp" / "conf")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-w", str(tmp_path / "wheel"), str(source)], check=True,
                   capture_output=True)
    (wheel,) = (tmp_path / "wheel").glob("semdp-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    index = zoo_data.read_index(REFERENCE_DIR / "zoo.yaml")
    assert "semdp/zoo/zoo.yaml" in names and "semdp/zoo_data.py" in names
    for run_dir in index.values():
        for name in zoo_data.REQUIRED:
            assert f"semdp/zoo/{run_dir}/{name}" in names, run_dir
    assert not any(n.endswith("progress.csv") for n in names)
    assert wheel.stat().st_size < 20_000_000  # about 10 MB: the policies are small
