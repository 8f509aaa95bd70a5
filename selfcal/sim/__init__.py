"""The simulated robot: MuJoCo models built with ``mujoco.MjSpec``, the marker scene, offscreen
rendering. Implements ``selfcal.robot.interface.Robot``; imports only the mathematics (never ``hw`` or the top layer).

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported. This is the one
place that sets the default, EGL (headless, no display); an explicit ``MUJOCO_GL`` wins. Every
module that imports ``mujoco`` is in this package, so the default is in place before it loads.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
