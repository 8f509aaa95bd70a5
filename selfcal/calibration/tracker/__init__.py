"""The tracker route: kinematics from tracker measurements of the tool,
its calibration file, and the joint fit with the images."""
