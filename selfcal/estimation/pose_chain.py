"""Board corners seen through a pose chain: the residual block of hand-eye calibration.

Every view ``i`` knows a rigid motion ``A_i`` (4, 4) from the robot's report, and the camera sees
the board through ``T_cam_board_i = X^-1 A_i B`` with two unknown transforms:

- eye-in-hand (camera on the flange, board static): ``A_i = T_flange_base_i`` (the inverse of
  the flange pose), ``X = T_flange_cam``, ``B = T_base_board``;
- eye-to-hand (camera static, board on the flange): ``A_i = T_base_flange_i``,
  ``X = T_base_cam``, ``B = T_flange_board``.

``X`` and ``B`` are parameterised locally, ``[w, v]`` (rotation vector, translation m) around
references ``X0``, ``B0``: ``R = Rot(w) R0``, ``t = t0 + v`` (:func:`local_pose`). The block's
rows are the board's corners (board coordinates, m, held) and their detected pixels; residual =
projected - observed (px); Jacobians are analytic w.r.t. the camera's free parameters, ``X`` and
``B``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.camera import CameraModel
from selfcal.estimation.pose_models import _rot, so3_left_jacobian
from selfcal.solver import Evaluation, JacobianPiece, Loss
from selfcal.transforms import make_pose, skew

__all__ = ["PoseChainBlock", "local_pose"]


def local_pose(T0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The pose ``[Rot(w) R0 | t0 + v]`` (4, 4) of the local parameters ``p = [w, v]`` (6,)
    around ``T0`` (4, 4)."""
    p = np.asarray(p, dtype=float)
    return make_pose(_rot(p[:3])[0] @ T0[:3, :3], T0[:3, 3] + p[3:])


class PoseChainBlock:
    """Board corners seen through ``T_cam_board_i = X^-1 A_i B`` (module docstring) as one
    residual block (``dim`` 2, px). ``A`` (n, 4, 4) m per view; rows ``view`` (k,), board points
    ``points`` (k, 3) m, pixels ``uv`` (k, 2); ``X0``, ``B0`` the references of the parameter
    blocks ``x_name`` and ``b_name`` (6 each); ``intrinsics`` the camera's free parameters."""

    dim = 2

    def __init__(
        self,
        camera: CameraModel,
        A: np.ndarray,
        X0: np.ndarray,
        B0: np.ndarray,
        view: np.ndarray,
        points: np.ndarray,
        uv: np.ndarray,
        loss: Loss | None = None,
        *,
        name: str = "pose_chain",
        intrinsics: str = "intrinsics",
        x_name: str = "X",
        b_name: str = "B",
    ) -> None:
        self.name = name
        self.loss = loss or Loss()
        self.camera = camera
        self.A = np.asarray(A, dtype=float)
        self.X0, self.B0 = np.asarray(X0, float), np.asarray(B0, float)
        self.view = np.asarray(view, dtype=np.int64)
        self.points = np.asarray(points, dtype=float).reshape(-1, 3)
        self.uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        self.keys = (intrinsics, x_name, b_name)
        k = len(self.view)
        self._cam_cols = np.broadcast_to(np.arange(camera.n_free)[None], (k, camera.n_free))
        self._six = np.broadcast_to(np.arange(6)[None], (k, 6))

    def camera_points(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Camera-frame points (k, 3) m at the parameter ``values``."""
        _, kx, kb = self.keys
        X, B = local_pose(self.X0, values[kx]), local_pose(self.B0, values[kb])
        return self._chain(X, B)[0]

    def _chain(self, X: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        RA = self.A[self.view, :3, :3]
        pb = self.points @ B[:3, :3].T  # R_B p
        q = np.einsum("kij,kj->ki", RA, pb + B[:3, 3]) + self.A[self.view, :3, 3]
        Xc = (q - X[:3, 3]) @ X[:3, :3]  # R_X^T (q - t_X)
        return Xc, q, pb

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (k, 2) px and the pieces d/d(camera), d/dX, d/dB."""
        ki, kx, kb = self.keys
        cam = self.camera.with_free_values(values[ki])
        px, pbv = np.asarray(values[kx], float), np.asarray(values[kb], float)
        X, B = local_pose(self.X0, px), local_pose(self.B0, pbv)
        Xc, q, pb = self._chain(X, B)
        if not jacobian:
            return Evaluation(cam.project(Xc) - self.uv)
        uv, Aproj, Jc = cam.project_free(Xc)
        RXt = X[:3, :3].T
        # X: dXc = R_X^T skew(q - t_X) J_l(w_X) dw - R_X^T dv
        dX = np.empty((len(Xc), 3, 6))
        dX[:, :, :3] = RXt @ skew(q - X[:3, 3]) @ so3_left_jacobian(px[:3])
        dX[:, :, 3:] = -RXt
        # B: dXc = R_X^T R_A (-skew(R_B p) J_l(w_B) dw + dv)
        M = RXt @ self.A[self.view, :3, :3]
        dB = np.empty((len(Xc), 3, 6))
        dB[:, :, :3] = -M @ skew(pb) @ so3_left_jacobian(pbv[:3])
        dB[:, :, 3:] = M
        return Evaluation(
            uv - self.uv,
            (
                JacobianPiece(ki, Jc, self._cam_cols),
                JacobianPiece(kx, Aproj @ dX, self._six),
                JacobianPiece(kb, Aproj @ dB, self._six),
            ),
        )
