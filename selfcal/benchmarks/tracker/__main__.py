"""``python -m selfcal.benchmarks.tracker``: the identification against pybotics (:mod:`.compare`)."""

from selfcal.benchmarks.tracker.compare import main

raise SystemExit(main())
