"""The real robot over a serial line (ACL), camera capture, and a controller emulator.

- ``hw.acl_protocol``: ACL reply reader, parsers, the serial link (``AclLink``).
- ``hw.encoders``: encoder counts <-> joint angles (``EncoderTable``).
- ``hw.acl_robot``: ``AclRobot``, the ``calib.robot.Robot`` over ACL;
  ``open_hardware_robot(scenario)`` for ``[robot] backend = "hardware"``.
- ``hw.cameras``: ``StereoCamera`` over ``cv2.VideoCapture``.
- ``hw.emulator``: ``AclEmulator`` (pty + TCP) with pluggable ``EmulatorBackend``.
- ``hw.cli``: ``register(subparsers)`` for ``hw joints|home|move`` and ``emulate``.

``sim.emulator_backend.SimEmulatorBackend`` puts a scenario's simulated robot behind the emulator.
"""
