"""``semdp-bench ab``: one command timed alternately on two versions of the code.

The base side here is a folder with a stand-in ``semdp`` package (``base_dir=``), the new side
the checkout; the timed command sleeps where a marker file says so, so the base side is the
slower one by construction and the printed ratio must say so. A side whose ``import semdp``
loads other code, a failing command and a missing command each stop the tool.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from semdp.benchmarks import ab
from semdp.cli.bench import SUITES

SLEEPY = [sys.executable, "-c",
          "import pathlib, time; time.sleep(0.3 if pathlib.Path('SLOW').exists() else 0.0)"]


def _stand_in(tmp_path: Path, slow: bool) -> Path:
    folder = tmp_path / "base"
    (folder / "semdp").mkdir(parents=True)
    (folder / "semdp" / "__init__.py").write_text("")
    if slow:
        (folder / "SLOW").write_text("")
    return folder


def test_ab_is_a_bench_suite() -> None:
    assert SUITES["ab"] == "semdp.benchmarks.ab"


def test_the_slower_side_is_reported_slower(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    base = _stand_in(tmp_path, slow=True)
    ab.main([f"base_dir={base}", "n=2", "--", *SLEEPY])
    out = capsys.readouterr().out
    rows = {line.split()[0]: line.split()[1:] for line in out.splitlines()
            if re.match(r"(base|new) +\d", line)}
    base_times = [float(t) for t in rows["base"][1:]]
    new_times = [float(t) for t in rows["new"][1:]]
    assert len(base_times) == len(new_times) == 2
    assert min(base_times) >= 0.3 > max(new_times)
    ratio = float(re.search(r"base / new = ([\d.]+)", out).group(1))
    # The medians are printed to 3 decimals: the ratio of the exact medians lies in the interval
    # the rounding leaves around the printed ones (a ~0.05 s median carries a ~1 % rounding).
    half = 0.0005
    base_median, new_median = float(rows["base"][0]), float(rows["new"][0])
    low = (base_median - half) / (new_median + half)
    high = (base_median + half) / (new_median - half)
    assert low - half <= ratio <= high + half
    assert "(new faster)" in out


def test_report_medians_and_ratio_by_hand() -> None:
    text = ab.report({"base": [3.0, 1.0, 2.0], "new": [1.0, 1.0, 4.0]})
    assert "base       2.000" in text and "new        1.000" in text
    assert "base / new = 2.000 (new faster)" in text


def test_a_side_that_imports_other_code_stops(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(SystemExit, match="editable_mode=compat"):
        ab.main([f"base_dir={empty}", "n=1", "--", *SLEEPY])


def test_a_failing_command_stops_with_its_output(tmp_path: Path) -> None:
    base = _stand_in(tmp_path, slow=False)
    with pytest.raises(SystemExit, match="exit 3"):
        ab.main([f"base_dir={base}", "n=1", "--", sys.executable, "-c",
                 "import sys; print('boom'); sys.exit(3)"])


@pytest.mark.parametrize("argv", [["n=2"], ["n=2", "--"], ["n=0", "--", "true"]])
def test_bad_arguments_stop(argv: list[str], tmp_path: Path) -> None:
    with pytest.raises(SystemExit):
        ab.main([f"base_dir={_stand_in(tmp_path, slow=False)}", *argv])
