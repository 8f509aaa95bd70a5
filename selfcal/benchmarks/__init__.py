"""Benchmark scripts (``python -m selfcal.benchmarks.NAME``): they time things
and regenerate the numbers the docs show."""
