"""``semdp-eval``: evaluate a finished run with evaluation-time changes (docs/evaluation.md).

:mod:`.options` parses the command line, :mod:`.config_edits` applies it to the run's saved
config, :mod:`.environment` builds the evaluation env, :mod:`.episodes` plays and summarises the
episodes, :mod:`.run` writes ``<run dir>/eval_<time>/``. Beside ``semdp-eval``, the Safety-Embedded
MDP's measurement tools (each ``python -m semdp.evaluation.<module>``): :mod:`.cost_trace` replays a
run's next epoch and records the low-level steps before each env's first cost step,
:mod:`.safety_eval` attributes every violation to its source, :mod:`.follower_eval` measures a
trajectory follower and :mod:`.follower_export` writes a trained follower's weights file.
"""
