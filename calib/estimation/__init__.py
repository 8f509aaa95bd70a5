"""Estimation problems built from residual blocks and handed to the one solver
(:mod:`calib.solver`).

- :mod:`calib.estimation.pose_models`: where camera poses come from (free, stereo rig);
- :mod:`calib.estimation.kinematic_poses`: camera poses from the MCPC kinematic chain;
- :mod:`calib.estimation.reprojection`: the projection and the image-observation residual block;
- :mod:`calib.estimation.residuals`: a known scene distance and Gaussian priors;
- :mod:`calib.estimation.joint_report`: the one-step refinement's covariances.

The drivers stay where callers import them: :func:`calib.bundle_adjust.bundle_adjust` and
:func:`calib.joint_refine.joint_refine`.
"""
