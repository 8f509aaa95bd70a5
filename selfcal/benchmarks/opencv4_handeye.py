"""The OpenCV side of the hand-eye comparison, run in an environment with OpenCV 4.x (OpenCV
5.0's Python bindings, the version in uv.lock, no longer expose the hand-eye functions):
:mod:`selfcal.benchmarks.handeye` starts it with ``uv run --no-project --with
'opencv-python-headless<5' --with numpy python selfcal/benchmarks/opencv4_handeye.py IN.npz OUT.npz``.

IN.npz: ``T_cam_board`` (m, 4, 4) the board poses OpenCV's camera calibration found (m),
``T_flange_base`` (m, 4, 4) the inverse of the robot's flange poses from its kinematics and
joint readings (m). OUT.npz: ``T_board_base`` and ``T_cam_flange`` (4, 4) of
``cv2.calibrateRobotWorldHandEye`` (Shah's method, OpenCV's default), ``version``.
"""

from __future__ import annotations

import sys


def main(argv: list[str]) -> int:
    """Solve and write OUT.npz (see the module docstring)."""
    import cv2
    import numpy as np

    d = np.load(argv[0])
    Tc, Tf = d["T_cam_board"], d["T_flange_base"]
    args = ([T[:3, :3] for T in Tc], [T[:3, 3] for T in Tc],
            [T[:3, :3] for T in Tf], [T[:3, 3] for T in Tf])  # fmt: skip
    R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(*args)

    def pose(R, t):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, np.ravel(t)
        return T

    np.savez(argv[1], T_board_base=pose(R_b2w, t_b2w), T_cam_flange=pose(R_g2c, t_g2c),
             version=cv2.__version__)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
