"""The guides state current behaviour only: no line of a guide carries a date, a commit hash or
a remark about the machine's load (history goes to CHANGELOG.md; how a folder of
``outputs/reference/`` was made goes to its ``COMMAND.md``).

The guides: the README, CONTRIBUTING.md, the documentation pages (``docs/``) and every other
``README.md`` of the repository (the package READMEs, ``outputs/reference/README.md``, the
follower weights' README). ``python tests/test_docs_history.py [<git ref>]`` prints, per
Markdown file outside CHANGELOG.md and the COMMAND.md files, how many lines have a date, a
hash or a load remark (at ``<git ref>`` when given).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_MONTH = (r"(?:Jan(?:uary)?|Feb(?:ruary)?|Mar(?:ch)?|Apr(?:il)?|May|June?|July?|Aug(?:ust)?"
          r"|Sep(?:t(?:ember)?)?|Oct(?:ober)?|Nov(?:ember)?|Dec(?:ember)?)\b\.?")
#: 2026-12-05, 2026-12, 5 Dec (2026), Dec 5, 22:35 UTC, and dates relative to a session.
DATE = re.compile(
    r"\b20\d\d-[01]\d(?:-[0-3]\d)?\b"
    rf"|\b\d{{1,2}} {_MONTH}(?: 20\d\d)?"
    rf"|\b{_MONTH} \d{{1,2}}(?:st|nd|rd|th)?\b"
    r"|\b\d\d:\d\d(?::\d\d)? ?UTC\b"
    r"|(?i:\b(?:today|yesterday|tonight|this session|last session)\b)")
#: A commit hash: 7-40 hex digits, with at least one digit and one letter, standing alone.
HASH = re.compile(r"(?<![\w/.#-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}(?![\w/-])")
#: How loaded the machine was when something was measured.
LOAD = re.compile(
    r"under load|\bload average|\bload \d|(?:busy|busiest|quiet|shared|idle) (?:\S+ )?machine"
    r"|machine (?:was|is) (?:quiet|shared|busy)|other sessions|second (?:training )?lane"
    r"|beside (?:a|another|other) (?:\w+ )?(?:lane|jobs?|benchmark)|nothing else running"
    r"|machine shared|other jobs? (?:was |were )?running",
    re.I)
KINDS = {"date": DATE, "hash": HASH, "load": LOAD}


def history_kinds(line: str) -> set[str]:
    """Which of date / hash / load a line carries."""
    return {kind for kind, pattern in KINDS.items() if pattern.search(line)}


def is_guide(path: str) -> bool:
    """A guide: the README, CONTRIBUTING.md, a docs page or any other README.md."""
    name = path.rsplit("/", 1)[-1]
    return path in ("README.md", "CONTRIBUTING.md") or (
        path.startswith("docs/") and name.endswith(".md")) or name == "README.md"


def markdown_files(ref: str | None = None) -> list[str]:
    """Tracked Markdown files (at ``ref``) outside CHANGELOG.md and the COMMAND.md files."""
    command = ["git", "ls-tree", "-r", "--name-only", ref] if ref else ["git", "ls-files"]
    names = subprocess.run(command, cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    return sorted(n for n in names if n.endswith(".md") and not n.endswith(
        ("CHANGELOG.md", "COMMAND.md")) and "/runs/" not in n)


def _text(path: str, ref: str | None) -> str:
    if ref is None:
        return (ROOT / path).read_text(encoding="utf-8")
    return subprocess.run(["git", "show", f"{ref}:{path}"], cwd=ROOT, capture_output=True,
                          text=True, check=True).stdout


def counts(text: str) -> dict[str, int]:
    """Lines with a date, a hash, a load remark, and with any of them."""
    found = {"lines": 0, "date": 0, "hash": 0, "load": 0, "any": 0}
    for line in text.splitlines():
        found["lines"] += 1
        kinds = history_kinds(line)
        for kind in kinds:
            found[kind] += 1
        found["any"] += bool(kinds)
    return found


def guides() -> list[Path]:
    return [ROOT / p for p in markdown_files() if is_guide(p)]


@pytest.mark.parametrize("guide", guides(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_dated_line_in_a_guide(guide: Path) -> None:
    lines = [f"{n}: {line.strip()[:120]}" for n, line in
             enumerate(guide.read_text(encoding="utf-8").splitlines(), start=1)
             if history_kinds(line)]
    assert lines == [], "history belongs in CHANGELOG.md:\n" + "\n".join(lines)


def test_the_guides_are_found() -> None:
    names = {str(p.relative_to(ROOT)) for p in guides()}
    assert {"README.md", "CONTRIBUTING.md", "docs/index.md", "docs/performance.md",
            "outputs/reference/README.md", "semdp/README.md"} <= names
    assert not any(n.endswith(("CHANGELOG.md", "COMMAND.md")) for n in names)


@pytest.mark.parametrize(
    ("line", "kinds"),
    [
        ("Measured on 2026-12-05 with the new kernels.", {"date"}),
        ("Status at 22:35 UTC: 11 of 36 runs.", {"date"}),
        ("The runs of 30 Nov were slower.", {"date"}),
        ("Rerun at today's code.", {"date"}),
        ("From a worktree of commit f716b01.", {"hash"}),
        ("at `70134c8`, as before", {"hash"}),
        ("an earlier run under load gave 0.32 ms", {"load"}),
        ("on a quiet machine; beside a second lane", {"load"}),
        ("6.6 min (shared 2-core machine)", {"load"}),
        ("85 s (one other job running)", {"load"}),
        ("2026-12-02 at 70134c8 (load 2.5-3.6)", {"date", "hash", "load"}),
    ],
)
def test_planted_history_is_found(line: str, kinds: set[str]) -> None:
    assert history_kinds(line) == kinds


@pytest.mark.parametrize(
    "line",
    ["`semdp-bench planner n=500 seed=0`: 500 problems, N = 30 waypoints, 0.43 ms median",
     "plans_sha256 `3f5a`; Table 3.1, Eqs. 3.3-3.8; 1.5 × 10⁶ env steps",
     "`outputs/reference/semdp_push1/runs/ours/point_push1_s0/eval.json`",
     "the MIT licence, 2026 The semdp authors; arXiv:2310.06903",
     "a decade of the LM's damping, 1e-3 to 1e3; deadbeef is not a hash",
     "margin 0.02 m, damping 1e-4; seed 1 may differ"],
)
def test_current_statements_are_not_history(line: str) -> None:
    assert history_kinds(line) == set()


def test_a_planted_dated_line_in_a_guide_fails(tmp_path: Path) -> None:
    page = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    assert counts(page)["any"] == 0
    planted = page + "\nThe main job took 7 min on 2026-12-05 (quiet machine, f716b01).\n"
    assert counts(planted) == {**counts(page), "lines": counts(page)["lines"] + 2,
                               "date": 1, "hash": 1, "load": 1, "any": 1}


def main(argv: list[str]) -> None:
    """Print the per-file table (at the git ref given, else the working tree)."""
    ref = argv[0] if argv else None
    print("| file | guide | lines | date | hash | load | any of them |")
    print("|---|---|---|---|---|---|---|")
    total = 0
    for path in markdown_files(ref):
        found = counts(_text(path, ref))
        total += found["any"] if is_guide(path) else 0
        if found["any"] or is_guide(path):
            print(f"| `{path}` | {'yes' if is_guide(path) else 'no'} | {found['lines']} | "
                  f"{found['date']} | {found['hash']} | {found['load']} | {found['any']} |")
    print(f"\nlines with history in the guides: {total}")


if __name__ == "__main__":
    main(sys.argv[1:])
