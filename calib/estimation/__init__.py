"""Estimation problems built from residual blocks and handed to the one solver
(:mod:`calib.solver`).

- :mod:`calib.estimation.pose_models`: where camera poses come from (free, rig of N cameras);
- :mod:`calib.estimation.kinematic_poses`: camera poses from the MCPC kinematic chain;
- :mod:`calib.estimation.reprojection`: the image-observation residual block (the projection is
  the camera model's, :mod:`calib.camera`);
- :mod:`calib.estimation.residuals`: a known scene distance and Gaussian priors;
- :mod:`calib.estimation.tracker`: tracker measurements of the tool (positions, poses, distances
  between tool positions) on the MCPC chain;
- :mod:`calib.estimation.joint_report`: the one-step refinement's covariances;
- the self-calibration's pieces: :mod:`calib.estimation.epipolar` (fundamental matrices between
  view pairs), :mod:`calib.estimation.focal` (fx, mu of the paper's pinhole from them),
  :mod:`calib.estimation.triangulation`, :mod:`calib.estimation.scale_sign` (the known distance
  and the sign) and :mod:`calib.estimation.selfcal_errors`.

The drivers stay where callers import them: :func:`calib.selfcal.self_calibrate` (with
:mod:`calib.selfcal_init` and :mod:`calib.selfcal_adjust`),
:func:`calib.bundle_adjust.bundle_adjust` and :func:`calib.joint_refine.joint_refine`.
"""
