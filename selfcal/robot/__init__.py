"""The robot: the ``Robot`` interface that sim and hw implement, and the robot
files (TOML tables, URDF, the kinematic chain, encoders) read into a ``RobotDef``."""
