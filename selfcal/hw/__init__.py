"""The real robot over a serial line (ACL), camera capture, and a controller emulator.

Implements ``selfcal.robot.interface.Robot``; imports only the mathematics (never ``sim`` or the top layer).

- ``selfcal.hw.acl.text``, ``selfcal.hw.acl.errors``, ``selfcal.hw.acl.reply``, ``selfcal.hw.acl.parsers``, ``selfcal.hw.acl.link``: ACL
  text on the wire, the error types and error lines, the reply reader, the reply parsers, the
  serial link (``AclLink``).
- ``selfcal.hw.encoders``: encoder counts <-> joint angles (``EncoderTable``).
- ``selfcal.hw.settings``: ``AclSettings``, the adapter's typed settings (the ``[robot.hardware]`` keys).
- ``selfcal.hw.acl.robot``: ``AclRobot``, the ``selfcal.robot.interface.Robot`` over ACL
  (``AclRobot.from_settings(settings)``), on ``selfcal.hw.acl.guard.AclGuard`` (latched controller errors,
  the abort sequence on failure).
- ``selfcal.hw.cameras``: ``StereoCamera`` over ``cv2.VideoCapture``.
- ``selfcal.hw.emulator.server``: ``AclEmulator`` (pty + TCP) with pluggable ``EmulatorBackend``
  (``selfcal.hw.emulator.backends``); its parts: ``selfcal.hw.emulator.motion`` (the arm's motion),
  ``selfcal.hw.emulator.controller`` (state and dialogue), ``selfcal.hw.emulator.faults`` (fault injection),
  ``selfcal.hw.emulator.transport`` (pty and TCP terminals).

What needs a scenario or the simulator lives in the top layer: ``selfcal.acquisition.hardware``
(``open_hardware_robot(scenario)`` for ``[robot] backend = "hardware"``), ``selfcal.cli.hw``
(``selfcal hw joints|home|move`` and ``emulate``) and ``selfcal.acquisition.emulator_backend``
(``SimEmulatorBackend``: a scenario's simulated robot behind the emulator).
"""
