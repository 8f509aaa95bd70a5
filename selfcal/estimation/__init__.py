"""Estimation problems built from residual blocks and handed to the one solver
(:mod:`selfcal.solver`).

- :mod:`selfcal.estimation.pose_models`: where camera poses come from (free, rig of N cameras);
- :mod:`selfcal.estimation.kinematic_poses`: camera poses from the MCPC kinematic chain;
- :mod:`selfcal.estimation.reprojection`: the image-observation residual block (the projection is
  the camera model's, :mod:`selfcal.camera`);
- :mod:`selfcal.estimation.residuals`: a known scene distance and Gaussian priors;
- :mod:`selfcal.estimation.tracker`: tracker measurements of the tool (positions, poses, distances
  between tool positions) on the MCPC chain;
- :mod:`selfcal.estimation.joint_report`: the one-step refinement's covariances;
- the self-calibration's pieces: :mod:`selfcal.estimation.epipolar` (fundamental matrices between
  view pairs), :mod:`selfcal.estimation.focal` (fx, mu of the paper's pinhole from them),
  :mod:`selfcal.estimation.triangulation`, :mod:`selfcal.estimation.scale_sign` (the known distance
  and the sign) and :mod:`selfcal.estimation.selfcal_errors`.

The drivers stay where callers import them: :func:`selfcal.calibration.field.self_calibration.self_calibrate` (with
:mod:`selfcal.calibration.field.initialise` and :mod:`selfcal.calibration.field.adjust`),
:func:`selfcal.estimation.bundle_adjust.bundle_adjust` and :func:`selfcal.calibration.field.joint_refine.joint_refine`.
"""
