"""The hand-eye against OpenCV 4.x: the joint board route (:mod:`.joints`, ``python -m
selfcal.benchmarks.handeye``), the pose route against OpenCV's seven methods (:mod:`.poses`) and
the OpenCV side, run in its own environment (:mod:`.opencv4`)."""
