"""``python -m selfcal.benchmarks.handeye``: the joint board route's comparison (:mod:`.joints`)."""

from selfcal.benchmarks.handeye.joints import main

raise SystemExit(main())
