"""Benchmarks of the recording plan (``selfcal plan``): the plan against random postures
(:mod:`.compare`) and ``--add K`` on a poorly identified dataset (:mod:`.add`)."""
