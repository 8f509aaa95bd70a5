"""The tracker identification against pybotics (:mod:`.compare`, ``python -m
selfcal.benchmarks.tracker``; pybotics' side in its own environment: :mod:`.pybotics_fit`) and
the simulated tracker sets both use (:mod:`.sim`)."""
