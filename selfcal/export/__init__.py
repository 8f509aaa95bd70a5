"""What users deploy: the calibrated chain in the robot's base frame, its TOML,
URDF and camera files, and IK with the calibrated model."""
