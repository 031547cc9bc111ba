"""Turn a sweep's run directories into tables and figures (``semdp-report``; docs/design.md)."""
