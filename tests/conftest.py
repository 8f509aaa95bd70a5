"""Shared test setup: headless rendering through MuJoCo's EGL backend unless told otherwise."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
