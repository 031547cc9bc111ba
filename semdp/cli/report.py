"""``semdp-report SWEEP_DIR [SWEEP_DIR ...] [--out DIR]``: tables and figures from sweeps
(docs/design.md).

Finds every run directory below each ``SWEEP_DIR`` (one holding ``metrics.json`` and/or
``progress.csv``; see :mod:`semdp.reporting.runs` for the fields used), groups runs by method label
(``metrics["label"]``, else ``metrics["algo"]``) and environment, and writes into ``--out``
(default ``<first SWEEP_DIR>/report``):

* ``table.md`` -- Table 3.1 layout: rows environment x {reward, cost}, columns methods, cells
  mean ± standard error over seeds of the final evaluation; with ``--compare A,B`` the
  difference A − B per environment ± its standard error and in standard errors
  (:mod:`semdp.reporting.compare`); with ``--late F`` the training episodes over the last
  fraction F of the epochs, with ``--at S1,S2`` the same for the runs cut at S env steps (what an
  earlier budget would have shown); then one line per failed or unfinished run naming it and why;
* ``curves_<env>.png`` -- episode return and cost vs env steps, one curve per method,
  Savitzky-Golay smoothed, shaded ±1 standard error over seeds;
* ``tradeoff_<env>.png`` -- Fig. B.1 (reward vs cost over ε') when runs carry ``tradeoff``.

Example::

    semdp-report outputs/multirun/semdp_push/laptop/<time> --out outputs/report/semdp_push
    semdp-report outputs/multirun/sp_safety_gym/laptop/<time> --compare SP-PPO-Lag,PPO-Lag
    semdp-report outputs/multirun/sp_driving/laptop/<time> --late 0.1 --at 150000,500000
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import NoReturn

from semdp.reporting.tables import parse_compare, parse_marks, write_report


class _Parser(argparse.ArgumentParser):
    """argparse with its errors in one line (argparse prints the usage above them)."""

    def error(self, message: str) -> NoReturn:
        sys.exit(f"{self.prog}: {message} (semdp-report --help shows the usage)")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (``semdp-report``)."""
    parser = _Parser(
        prog="semdp-report",
        description="Tables (mean ± SE over seeds), training curves and the ε' trade-off "
        "scatter from a sweep's run directories.",
    )
    parser.add_argument("sweep_dir", type=Path, nargs="+",
                        help="sweep or parent directory of run dirs (several: reported together)")
    parser.add_argument("--out", type=Path, default=None, help="output dir (default SWEEP/report)")
    parser.add_argument("--digits", type=int, default=2, help="decimals in table cells")
    parser.add_argument(
        "--order", default="", help="comma-separated method labels to put first (table columns)"
    )
    parser.add_argument(
        "--compare", default="", help="two method labels A,B: add the differences A - B"
    )
    parser.add_argument(
        "--late", type=float, default=0.0,
        help="also tabulate the training episodes over this last fraction of the epochs",
    )
    parser.add_argument(
        "--at", default="",
        help="comma-separated env-step marks (e.g. 150000): the training-episode table of "
        "runs stopped there (the --late fraction, else 10%%, of the epochs up to the mark)",
    )
    args = parser.parse_args(argv)
    if args.digits < 0:
        parser.error(f"--digits must be >= 0, got {args.digits}")
    if not 0.0 <= args.late <= 1.0:  # NaN included
        parser.error(f"--late must be a fraction in [0, 1], got {args.late}")
    out_dir = args.out if args.out is not None else args.sweep_dir[0] / "report"
    try:
        order = [label.strip() for label in args.order.split(",") if label.strip()]
        written = write_report(args.sweep_dir, out_dir, args.digits, order,
                               parse_compare(args.compare), args.late, parse_marks(args.at))
    except ValueError as exc:
        sys.exit(f"semdp-report: {exc}")
    print(written[0].read_text())
    for path in written:
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
