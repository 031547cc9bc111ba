"""``semdp-eval``: evaluate a finished run with evaluation-time changes (semdp/README.md,
"Evaluating a trained run").

:mod:`.options` parses the command line, :mod:`.config_edits` applies it to the run's saved
config, :mod:`.environment` builds the evaluation env, :mod:`.episodes` plays and summarises the
episodes, :mod:`.run` writes ``<run dir>/eval_<time>/``.
"""
