"""Benchmark suites run by ``semdp-bench``; each prints a table and writes a CSV."""
