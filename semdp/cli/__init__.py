"""The command-line apps, thin on purpose: each composes its Hydra config (or parses its
arguments) and calls the library (:mod:`semdp.build`, :mod:`semdp.evaluation`,
:mod:`semdp.reporting`, :mod:`semdp.benchmarks`, :mod:`solvers`); library code never imports
them (tests/test_layering.py).

``semdp-train`` (:mod:`.train`), ``semdp-eval`` (:mod:`.eval`), ``semdp-plan`` (:mod:`.plan`),
``semdp-toy`` (:mod:`.toy`), ``semdp-bench`` (:mod:`.bench`), ``semdp-report`` (:mod:`.report`);
what they share: :mod:`.one_line` (errors in one line), :mod:`.override_types`, and
:mod:`.run_logging` (what ``semdp-train`` adds to a run's ``progress.csv`` logging).
"""
