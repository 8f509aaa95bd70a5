"""The OpenCV side of the hand-eye comparisons, run in an environment with OpenCV 4.x (OpenCV
5.0's Python bindings, the version in uv.lock, no longer expose the hand-eye functions). It
imports nothing of selfcal: the benchmarks start it with ``uv run --no-project --with
'opencv-python-headless<5' --with numpy python selfcal/benchmarks/handeye/opencv4.py IN OUT``.

Two modes, by IN's suffix:

- ``IN.npz`` (:mod:`selfcal.benchmarks.handeye`, the joint board route): ``T_cam_board``
  (m, 4, 4) the board poses OpenCV's camera calibration found (m), ``T_flange_base`` (m, 4, 4)
  the inverse of the robot's flange poses from its kinematics and joint readings (m). OUT.npz:
  ``T_board_base`` and ``T_cam_flange`` (4, 4) of ``cv2.calibrateRobotWorldHandEye`` (Shah's
  method, OpenCV's default), ``version``.
- ``IN.json`` (:mod:`selfcal.benchmarks.handeye.poses`, the pose route): ``cases``, each
  ``{"size": [W, H], "flags": [names of calibrateCamera's flags], "train": {"object": [(k, 3) m per
  frame], "image": [(k, 2) px per frame], "A": [(4, 4) per frame]}, "held": {"object": [...],
  "A": [...]}}`` where ``A_i`` are the pose chain's motions: every frame sees the board through
  ``T_cam_board_i = X^-1 A_i B`` (:mod:`selfcal.estimation.pose_chain`). Per case OpenCV's own
  route: ``cv2.calibrateCamera`` on the training frames (the camera and the board poses
  ``C_i``), then each of the five ``cv2.calibrateHandEye`` methods (gripper -> base =
  ``A_i^-1``, target -> camera = ``C_i``; it returns camera -> gripper = ``X``; the board mount
  ``B`` is then the mean over the training frames of ``A_i^-1 X C_i``: the chordal mean of the
  rotations, the rotation nearest their sum, and the mean of the translations) and the two
  ``cv2.calibrateRobotWorldHandEye`` methods (world -> camera = ``C_i``, base -> gripper =
  ``A_i``; it returns base -> world = ``B^-1`` and gripper -> camera = ``X^-1``). Each predicts
  the held-out frames' corners from their motions alone (``cv2.projectPoints``; NaN for a
  corner behind the camera). OUT.json: ``version`` and per case ``camera`` (``K``, ``dist``,
  ``rms``) and ``methods``: name -> ``{"X", "B", "pred": [(k, 2) per held-out frame]}`` or
  ``{"error": text}``.
"""

from __future__ import annotations

import json
import sys

HAND_EYE = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")
ROBOT_WORLD = ("SHAH", "LI")


def _pose(R, t):
    import numpy as np

    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def _inv(T):
    R, t = T[:3, :3], T[:3, 3]
    return _pose(R.T, -R.T @ t)


def _mean_pose(T):
    """The chordal mean of the rotations of ``T`` (n, 4, 4) and the mean of their translations."""
    import numpy as np

    U, _, Vt = np.linalg.svd(T[:, :3, :3].sum(axis=0))
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return _pose(R, T[:, :3, 3].mean(axis=0))


def _predict(cv2, np, K, dist, X, B, A, objects):
    out = []
    for Ai, P in zip(A, objects, strict=True):
        T = _inv(X) @ Ai @ B
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        uv = cv2.projectPoints(P, rvec, T[:3, 3], K, dist)[0].reshape(-1, 2)
        z = P @ T[2, :3] + T[2, 3]
        out.append(np.where(z[:, None] > 0, uv, np.nan).tolist())
    return out


def _case(cv2, np, case: dict) -> dict:
    train, held = case["train"], case["held"]
    obj = [np.asarray(p, np.float32).reshape(-1, 1, 3) for p in train["object"]]
    img = [np.asarray(p, np.float32).reshape(-1, 1, 2) for p in train["image"]]
    flags = sum(getattr(cv2, f) for f in case["flags"])
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, tuple(case["size"]), None, None,
                                                     flags=flags)  # fmt: skip
    C = np.array([_pose(cv2.Rodrigues(r)[0], t) for r, t in zip(rvecs, tvecs, strict=True)])
    A = np.asarray(train["A"], float)
    G = np.array([_inv(a) for a in A])
    A_held = np.asarray(held["A"], float)
    P_held = [np.asarray(p, float) for p in held["object"]]
    methods = {}
    for name in HAND_EYE + ROBOT_WORLD:
        try:
            if name in HAND_EYE:
                R, t = cv2.calibrateHandEye(
                    list(G[:, :3, :3]), list(G[:, :3, 3]), list(C[:, :3, :3]), list(C[:, :3, 3]),
                    method=getattr(cv2, f"CALIB_HAND_EYE_{name}"),
                )  # fmt: skip
                X = _pose(R, t)
                B = _mean_pose(G @ X @ C)
            else:
                R_bw, t_bw, R_gc, t_gc = cv2.calibrateRobotWorldHandEye(
                    list(C[:, :3, :3]), list(C[:, :3, 3]), list(A[:, :3, :3]), list(A[:, :3, 3]),
                    method=getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{name}"),
                )  # fmt: skip
                X, B = _inv(_pose(R_gc, t_gc)), _inv(_pose(R_bw, t_bw))
        except (cv2.error, np.linalg.LinAlgError) as exc:
            methods[name] = {"error": str(exc).strip().splitlines()[-1][:200]}
            continue
        if np.isfinite(X).all() and np.isfinite(B).all():
            methods[name] = {"X": X.tolist(), "B": B.tolist(),
                             "pred": _predict(cv2, np, K, dist, X, B, A_held, P_held)}  # fmt: skip
        else:
            methods[name] = {"error": "returned NaN"}
    return {"camera": {"K": K.tolist(), "dist": dist.ravel().tolist(), "rms": float(rms)},
            "methods": methods}  # fmt: skip


def _robot_world_npz(cv2, np, src: str, dst: str) -> None:
    with np.load(src) as d:
        Tc, Tf = d["T_cam_board"], d["T_flange_base"]
    args = ([T[:3, :3] for T in Tc], [T[:3, 3] for T in Tc],
            [T[:3, :3] for T in Tf], [T[:3, 3] for T in Tf])  # fmt: skip
    R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(*args)
    np.savez(dst, T_board_base=_pose(R_b2w, t_b2w), T_cam_flange=_pose(R_g2c, t_g2c),
             version=cv2.__version__)  # fmt: skip


def main(argv: list[str]) -> int:
    """Solve and write OUT (see the module docstring)."""
    import cv2
    import numpy as np

    src, dst = argv
    if src.endswith(".npz"):
        _robot_world_npz(cv2, np, src, dst)
        return 0
    with open(src) as f:
        cases = json.load(f)["cases"]
    out = {"version": cv2.__version__, "cases": [_case(cv2, np, c) for c in cases]}
    with open(dst, "w") as f:
        json.dump(out, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
