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

Errors in variables: with a ``corrections`` parameter block (6 per view, one instance each, so
the solver's Schur path eliminates them) the reported flange pose ``T_base_flange_i`` of every
view is itself an unknown, ``local_pose(T_base_flange_i, c_i)`` (its rotation turned by
``Rot(w_i)`` about the flange's origin, its origin moved by ``v_i`` in the base frame), and
:class:`FlangePriorBlock` ties each correction to zero with the pose sensor's noise
(:mod:`selfcal.calibration.handeye.eiv` weighs the two).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.camera import CameraModel
from selfcal.estimation.pose_models import _rot, so3_left_jacobian
from selfcal.solver import Evaluation, JacobianPiece, Loss
from selfcal.transforms import inv_pose, make_pose, skew

__all__ = ["FlangePriorBlock", "PoseChainBlock", "local_pose"]


def local_pose(T0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The pose ``[Rot(w) R0 | t0 + v]`` (4, 4) of the local parameters ``p = [w, v]`` (6,)
    around ``T0`` (4, 4)."""
    p = np.asarray(p, dtype=float)
    return make_pose(_rot(p[:3])[0] @ T0[:3, :3], T0[:3, 3] + p[3:])


class PoseChainBlock:
    """Board corners seen through ``T_cam_board_i = X^-1 A_i B`` (module docstring) as one
    residual block (``dim`` 2, px). ``A`` (n, 4, 4) m per view; rows ``view`` (k,), board points
    ``points`` (k, 3) m, pixels ``uv`` (k, 2); ``X0``, ``B0`` the references of the parameter
    blocks ``x_name`` and ``b_name`` (6 each); ``intrinsics`` the camera's free parameters.
    ``corrections`` (a block name, or None: the poses exact): the block of the views' flange
    pose corrections (6 n, ``[w, v]`` per view, module docstring); ``inverted``: ``A_i`` is the
    inverse of the flange pose (eye-in-hand), else the flange pose itself (eye-to-hand)."""

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
        corrections: str | None = None,
        inverted: bool = False,
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
        self.corrections, self.inverted = corrections, inverted
        # the reported flange poses T_base_flange (the corrections' references)
        self.F0 = inv_pose(self.A) if inverted else self.A
        k = len(self.view)
        self._cam_cols = np.broadcast_to(np.arange(camera.n_free)[None], (k, camera.n_free))
        self._six = np.broadcast_to(np.arange(6)[None], (k, 6))
        self._view_cols = 6 * self.view[:, None] + np.arange(6)[None]

    def _motions(self, values: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
        """The rows' motions ``A`` (k, 4, 4) at ``values`` and the rows' corrections (k, 6)
        (None without a corrections block)."""
        if self.corrections is None:
            return self.A[self.view], None
        c = np.asarray(values[self.corrections], float).reshape(-1, 6)
        F0 = self.F0
        F = np.empty_like(F0)
        F[:] = np.eye(4)
        F[:, :3, :3] = _rot(c[:, :3]) @ F0[:, :3, :3]
        F[:, :3, 3] = F0[:, :3, 3] + c[:, 3:]
        A = inv_pose(F) if self.inverted else F
        return A[self.view], c[self.view]

    def camera_points(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Camera-frame points (k, 3) m at the parameter ``values``."""
        _, kx, kb = self.keys
        X, B = local_pose(self.X0, values[kx]), local_pose(self.B0, values[kb])
        return self._chain(X, B, self._motions(values)[0])[0]

    def _chain(
        self, X: np.ndarray, B: np.ndarray, A: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Camera-frame points (k, 3), the points in X's parent frame ``q`` and ``R_B p``
        through the rows' motions ``A`` (k, 4, 4)."""
        pb = self.points @ B[:3, :3].T  # R_B p
        q = np.einsum("kij,kj->ki", A[:, :3, :3], pb + B[:3, 3]) + A[:, :3, 3]
        Xc = (q - X[:3, 3]) @ X[:3, :3]  # R_X^T (q - t_X)
        return Xc, q, pb

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (k, 2) px and the pieces d/d(camera), d/dX, d/dB (and d/d(corrections))."""
        ki, kx, kb = self.keys
        cam = self.camera.with_free_values(values[ki])
        px, pbv = np.asarray(values[kx], float), np.asarray(values[kb], float)
        X, B = local_pose(self.X0, px), local_pose(self.B0, pbv)
        A, c = self._motions(values)
        Xc, q, pb = self._chain(X, B, A)
        if not jacobian:
            return Evaluation(cam.project(Xc) - self.uv)
        uv, Aproj, Jc = cam.project_free(Xc)
        RXt = X[:3, :3].T
        # X: dXc = R_X^T skew(q - t_X) J_l(w_X) dw - R_X^T dv
        dX = np.empty((len(Xc), 3, 6))
        dX[:, :, :3] = RXt @ skew(q - X[:3, 3]) @ so3_left_jacobian(px[:3])
        dX[:, :, 3:] = -RXt
        # B: dXc = R_X^T R_A (-skew(R_B p) J_l(w_B) dw + dv)
        M = RXt @ A[:, :3, :3]
        dB = np.empty((len(Xc), 3, 6))
        dB[:, :, :3] = -M @ skew(pb) @ so3_left_jacobian(pbv[:3])
        dB[:, :, 3:] = M
        pieces = [
            JacobianPiece(ki, Jc, self._cam_cols),
            JacobianPiece(kx, Aproj @ dX, self._six),
            JacobianPiece(kb, Aproj @ dB, self._six),
        ]
        if self.corrections is not None and c is not None:
            pieces.append(
                JacobianPiece(
                    self.corrections,
                    Aproj @ (RXt @ self._dq_dc(A, c, pb + B[:3, 3])),
                    self._view_cols,
                )  # fmt: skip
            )
        return Evaluation(uv - self.uv, tuple(pieces))

    def _dq_dc(self, A: np.ndarray, c: np.ndarray, y: np.ndarray) -> np.ndarray:
        """d q / d(correction) (k, 3, 6) of ``q = R_A y + t_A`` (``y = R_B p + t_B``)."""
        Jl = so3_left_jacobian(c[:, :3])
        out = np.empty((len(y), 3, 6))
        if self.inverted:  # q = R_F^T (y - t_F), F = [Rot(w) R0 | t0 + v]
            RFt = A[:, :3, :3]
            t_F = -np.einsum("kji,kj->ki", RFt, A[:, :3, 3])  # t_F = -R_F t_A
            out[:, :, :3] = RFt @ skew(y - t_F) @ Jl
            out[:, :, 3:] = -RFt
        else:  # q = Rot(w) R0 y + t0 + v
            out[:, :, :3] = -skew(np.einsum("kij,kj->ki", A[:, :3, :3], y)) @ Jl
            out[:, :, 3:] = np.eye(3)
        return out


class FlangePriorBlock:
    """The prior of the flange pose corrections (``dim`` 6, one row per view): the correction
    ``[w, v]`` of each view times ``scale`` (6,) = reference sigma / the pose sensor's sigma per
    coordinate (px per rad for ``w``, px per m for ``v`` when the image rows are in px), so that
    its rows weigh as the image rows of the same problem (module docstring)."""

    dim = 6

    def __init__(self, n_views: int, scale: np.ndarray, *, name: str = "flange_prior",
                 corrections: str = "corrections") -> None:  # fmt: skip
        self.name = name
        self.loss = Loss()
        self.n = int(n_views)
        self.scale = np.broadcast_to(np.asarray(scale, float), (6,)).copy()
        self.corrections = corrections
        self._cols = np.arange(6 * self.n).reshape(self.n, 6)
        self._J = np.broadcast_to(np.diag(self.scale)[None], (self.n, 6, 6))

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (n, 6): the scaled corrections; the piece d/d(corrections)."""
        r = np.asarray(values[self.corrections], float).reshape(self.n, 6) * self.scale
        if not jacobian:
            return Evaluation(r)
        return Evaluation(r, (JacobianPiece(self.corrections, self._J, self._cols),))
