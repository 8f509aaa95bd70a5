"""One piece's time each: the pipeline by stage (:mod:`.stages`), the identification, the
self-calibration and the joint refinement, the kinematics, the renderer, the ACL reply reader,
the bag import and a study on a cluster."""
