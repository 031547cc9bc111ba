"""``semdp-bench SUITE [args...]``: benchmark dispatcher.

Each suite lives in :mod:`semdp.benchmarks` as a module with ``main(argv: list[str]) -> None``
that prints a table and writes a CSV. Examples::

    semdp-bench planner backends=[ipopt,lm,scp]
    semdp-bench sims
    semdp-bench driving
    semdp-bench ab base=HEAD~1 -- semdp-bench semdp steps=2000   # two versions, side by side
"""

from __future__ import annotations

import importlib
import sys

SUITES: dict[str, str] = {
    "planner": "semdp.benchmarks.planner",
    "sims": "semdp.benchmarks.sims",
    "driving": "semdp.benchmarks.driving",
    "train": "semdp.benchmarks.train",
    "semdp": "semdp.benchmarks.semdp",
    "safety": "semdp.benchmarks.safety",
    "price": "semdp.benchmarks.price",
    "ab": "semdp.benchmarks.ab",
}


def main(argv: list[str] | None = None) -> None:
    """Run one benchmark suite by name."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in {"-h", "--help"} or argv[0] not in SUITES:
        given = f"unknown suite {argv[0]!r}; " if argv and argv[0] not in {"-h", "--help"} else ""
        sys.exit(f"semdp-bench: {given}usage: semdp-bench SUITE [args...], SUITE one of "
                 f"{', '.join(SUITES)}")
    module = importlib.import_module(SUITES[argv[0]])
    module.main(argv[1:])


if __name__ == "__main__":
    main()
