"""Turn a sweep's run directories into tables and figures (``semdp-report``, SPEC §4.3)."""
