"""Turn a sweep's run directories into tables and figures (``semdp-report``; docs/design.md), and
a finished SEMDP run into its artefacts (:mod:`.semdp_run`, the ``post_train`` hook)."""
