"""``semdp-eval``: evaluate a finished run with evaluation-time changes (semdp/README.md,
"Evaluating a trained run").

:mod:`.options` parses the command line, :mod:`.config_edits` applies it to the run's saved
config, :mod:`.environment` builds the evaluation env, :mod:`.episodes` plays and summarises the
episodes, :mod:`.run` writes ``<run dir>/eval_<time>/``. Beside ``semdp-eval``: :mod:`.cost_trace`
(``python -m semdp.evaluation.cost_trace``) replays a run's next epoch and records the low-level
steps before each env's first cost step.
"""
