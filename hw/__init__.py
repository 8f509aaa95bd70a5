"""The real robot over a serial line (ACL), camera capture, and a controller emulator.

Implements ``calib.robot.Robot``; imports only ``calib`` (never ``sim`` or ``scenarios``).

- ``hw.acl_text``, ``hw.acl_errors``, ``hw.acl_reply``, ``hw.acl_parsers``, ``hw.acl_link``: ACL
  text on the wire, the error types and error lines, the reply reader, the reply parsers, the
  serial link (``AclLink``).
- ``hw.encoders``: encoder counts <-> joint angles (``EncoderTable``).
- ``hw.settings``: ``AclSettings``, the adapter's typed settings (the ``[robot.hardware]`` keys).
- ``hw.acl_robot``: ``AclRobot``, the ``calib.robot.Robot`` over ACL
  (``AclRobot.from_settings(settings)``), on ``hw.acl_guard.AclGuard`` (latched controller errors,
  the abort sequence on failure).
- ``hw.cameras``: ``StereoCamera`` over ``cv2.VideoCapture``.
- ``hw.emulator``: ``AclEmulator`` (pty + TCP) with pluggable ``EmulatorBackend``
  (``hw.emulator_backends``); its parts: ``hw.emulator_motion`` (the arm's motion),
  ``hw.emulator_controller`` (state and dialogue), ``hw.emulator_faults`` (fault injection),
  ``hw.emulator_transport`` (pty and TCP terminals).

What needs a scenario or the simulator lives in ``scenarios``: ``scenarios.hardware``
(``open_hardware_robot(scenario)`` for ``[robot] backend = "hardware"``), ``scenarios.hw_cli``
(``selfcal hw joints|home|move`` and ``emulate``) and ``scenarios.emulator_backend``
(``SimEmulatorBackend``: a scenario's simulated robot behind the emulator).
"""
