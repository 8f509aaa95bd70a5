"""Benchmark scripts (``python -m selfcal.benchmarks.PART.NAME``): they time things and
regenerate the numbers the docs show, in a folder for each part (board, drift, handeye, plan,
speed, timing, tracker); the modules here are what the parts share (the docs' generated blocks,
the map over draws, a child process's measures, the detector's corner noise)."""
