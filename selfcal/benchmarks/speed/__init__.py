"""The speed the README states (issues 17 and 32): the speed benchmark (:mod:`.measure`, its
tables :mod:`.table`, side by side with a git ref :mod:`.against` and :mod:`.pairs`), the times
of ``docs/measurements.toml`` (:mod:`.times`) and one ``selfcal run``'s timeline
(:mod:`.run_timeline`)."""
