"""Observation container, error classes and sparse bundle adjustment for the self-calibration stage.

Frames and units (see docs/DEVELOPING.md): poses ``T_cam_world`` map world coordinates to the OpenCV
camera frame (x right, y down, z forward); pixels follow the OpenCV convention. Intrinsics are the
paper's eq. 19 with a known principal point: ``K = [[fx, 0, cx], [0, mu fx, cy], [0, 0, 1]]``.

Views are indexed ``view = 2 * config + camera`` with ``camera`` 0 = left, 1 = right.

Pluggable camera poses
----------------------
The bundle adjustment never sees per-view pose parameters directly: it asks a *pose model*
(:class:`PoseModel`) for ``poses(p) -> T_cam_world (V, 4, 4)``, for the parameter columns each view
depends on (``view_columns() -> (V, q)`` int, ``-1`` = unused slot) and, optionally, for the
derivative of each view pose as a left-perturbation twist in the camera frame
(``view_jacobian(p) -> (V, 6, q)``, twist order ``[v; w]`` as in :mod:`calib.transforms`): a change
``dp`` moves camera coordinates by ``dXc = dv + dw x Xc`` with ``[dv; dw] = J_v dp``.
:class:`FreePoses` (one 6-dof pose per view) and :class:`RigPoses` (one pose per configuration plus
a shared left->right rig transform) are the two models provided here; a kinematic-chain model
(poses from joint angles and MCPC parameters) only has to implement the same three methods, with
``view_jacobian`` obtained from the identification Jacobian. If ``view_jacobian`` returns ``None``
the adjustment falls back to finite differences restricted by ``jac_sparsity``. The pose model also
owns the gauge: the models here fix one camera at the identity and one baseline length to 1.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.spatial.transform import Rotation

from calib.errors import EstimationError
from calib.transforms import adjoint, make_pose, skew

__all__ = [
    "Observations",
    "point_id",
    "marker_corner",
    "SelfCalibrationError",
    "InsufficientDataError",
    "DegenerateConfigurationError",
    "ScaleMarkerError",
    "ConvergenceError",
    "so3_left_jacobian",
    "PoseModel",
    "FreePoses",
    "RigPoses",
    "BundleResult",
    "bundle_adjust",
    "reprojection_residuals",
    "intrinsics_covariance",
]

LEFT, RIGHT = 0, 1
_CAMERA_NAMES = {"left": LEFT, "right": RIGHT, "l": LEFT, "r": RIGHT, 0: LEFT, 1: RIGHT}


# ----------------------------------------------------------------------------------- errors
class SelfCalibrationError(EstimationError):
    """Base class: the camera self-calibration cannot produce a trustworthy result."""


class InsufficientDataError(SelfCalibrationError):
    """Too few views, shared points or correspondences for a step of the pipeline."""


class DegenerateConfigurationError(SelfCalibrationError):
    """The viewing geometry does not determine the unknowns (e.g. optical axes through one point,
    pure rotation, planar scene)."""


class ScaleMarkerError(SelfCalibrationError):
    """The scale markers are missing from the reconstruction or the distance is invalid."""


class ConvergenceError(SelfCalibrationError):
    """An optimisation did not converge or ended with implausible residuals."""


# ----------------------------------------------------------------------------- observations
def point_id(marker_id: np.ndarray | int, corner: np.ndarray | int) -> np.ndarray | int:
    """Point id ``4 * marker_id + corner`` (corner 0..3 in ArUco order)."""
    return (
        4 * np.asarray(marker_id) + np.asarray(corner)
        if np.ndim(marker_id)
        else (4 * int(marker_id) + int(corner))
    )


def marker_corner(pid: np.ndarray | int) -> tuple[np.ndarray, np.ndarray] | tuple[int, int]:
    """Inverse of :func:`point_id`: ``(marker_id, corner)``."""
    if np.ndim(pid):
        return np.divmod(np.asarray(pid), 4)
    return divmod(int(pid), 4)


@dataclass(frozen=True)
class Observations:
    """2-D observations of 3-D points, one row per (view, point).

    ``config`` (k,) int in ``0..n_configs-1``; ``camera`` (k,) int, 0 = left, 1 = right;
    ``point`` (k,) int point id ``4 * marker_id + corner``; ``uv`` (k, 2) float pixels (OpenCV).
    The view index used everywhere else is ``view = 2 * config + camera``.
    """

    config: np.ndarray
    camera: np.ndarray
    point: np.ndarray
    uv: np.ndarray
    n_configs: int

    def __post_init__(self) -> None:
        cfg = np.asarray(self.config, dtype=np.int64).reshape(-1)
        cam = np.asarray(self.camera, dtype=np.int64).reshape(-1)
        pt = np.asarray(self.point, dtype=np.int64).reshape(-1)
        uv = np.asarray(self.uv, dtype=float).reshape(-1, 2)
        k = len(cfg)
        if not (len(cam) == len(pt) == len(uv) == k):
            raise ValueError(
                f"Observations arrays differ in length: config {k}, camera {len(cam)}, "
                f"point {len(pt)}, uv {len(uv)}; give one row per observation"
            )
        if k and (cfg.min() < 0 or cfg.max() >= self.n_configs):
            raise ValueError(f"config indices must lie in 0..{self.n_configs - 1}")
        if k and not np.isin(cam, (LEFT, RIGHT)).all():
            raise ValueError("camera must be 0 (left) or 1 (right)")
        if k and pt.min() < 0:
            raise ValueError("point ids must be >= 0 (4 * marker_id + corner)")
        if not np.isfinite(uv).all():
            raise ValueError("uv contains NaN/inf; drop undetected corners instead")
        key = (2 * cfg + cam) * (int(pt.max()) + 1 if k else 1) + pt
        if len(np.unique(key)) != k:
            raise ValueError("a point is observed twice in the same view; deduplicate detections")
        for name, val in (("config", cfg), ("camera", cam), ("point", pt), ("uv", uv)):
            val.setflags(write=False)
            object.__setattr__(self, name, val)

    @classmethod
    def from_corners(
        cls,
        detections: Mapping[tuple[int, int | str], Mapping[int, np.ndarray]],
        n_configs: int | None = None,
    ) -> Observations:
        """Build from ``{(config, camera): {marker_id: corners (4, 2) px}}``.

        ``camera`` is 0/1 or "left"/"right". ``n_configs`` defaults to the largest config + 1
        (configurations without any detection are allowed and stay unregistered).
        """
        cfg, cam, pt, uv = [], [], [], []
        for (c, camera), markers in detections.items():
            if camera not in _CAMERA_NAMES:
                raise ValueError(f"camera {camera!r} is not 0/1/'left'/'right'")
            for mid, corners in markers.items():
                corners = np.asarray(corners, dtype=float)
                if corners.shape != (4, 2):
                    raise ValueError(
                        f"marker {mid} in view {(c, camera)}: corners must have shape (4, 2), "
                        f"got {corners.shape}"
                    )
                cfg.extend([int(c)] * 4)
                cam.extend([_CAMERA_NAMES[camera]] * 4)
                pt.extend(4 * int(mid) + np.arange(4))
                uv.append(corners)
        if n_configs is None:
            n_configs = max(cfg) + 1 if cfg else 0
        uv_arr = np.concatenate(uv) if uv else np.zeros((0, 2))
        return cls(np.array(cfg), np.array(cam), np.array(pt), uv_arr, int(n_configs))

    @property
    def view(self) -> np.ndarray:
        """View index ``2 * config + camera`` (k,)."""
        return 2 * self.config + self.camera

    @property
    def n_views(self) -> int:
        return 2 * self.n_configs

    def __len__(self) -> int:
        return len(self.config)

    def point_index(self) -> tuple[np.ndarray, np.ndarray]:
        """``(point_ids (P,), index (k,))``: the distinct point ids, sorted, and each row's index
        into them."""
        ids, inv = np.unique(self.point, return_inverse=True)
        return ids, inv

    def subset(self, mask: np.ndarray) -> Observations:
        """Rows selected by a boolean mask or index array."""
        return Observations(
            self.config[mask], self.camera[mask], self.point[mask], self.uv[mask], self.n_configs
        )


# ------------------------------------------------------------------------------ SO(3) helper
def so3_left_jacobian(w: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3) at rotation vectors ``w`` (..., 3): ``exp(w + dw) ~
    exp(J_l(w) dw) exp(w)``."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    W = skew(w)
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ths)) / ths**2)
    b = np.where(small, 1.0 / 6.0 - th**2 / 120.0, (ths - np.sin(ths)) / ths**3)
    return np.eye(3) + a * W + b * (W @ W)


def _rot(w: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(np.asarray(w, dtype=float).reshape(-1, 3)).as_matrix()


def _tangent_basis(t: np.ndarray) -> np.ndarray:
    """Orthonormal (3, 2) basis of the plane perpendicular to unit vector ``t``."""
    a = np.eye(3)[np.argmin(np.abs(t))]
    u1 = np.cross(t, a)
    u1 /= np.linalg.norm(u1)
    return np.stack([u1, np.cross(t, u1)], axis=1)


# ------------------------------------------------------------------------------ pose models
@runtime_checkable
class PoseModel(Protocol):
    """Source of the camera poses in the bundle adjustment (see the module docstring)."""

    n_views: int
    n_params: int

    def poses(self, p: np.ndarray) -> np.ndarray:
        """``T_cam_world`` (V, 4, 4); NaN for views that have no pose."""

    def view_columns(self) -> np.ndarray:
        """(V, q) int: pose-parameter indices each view depends on, ``-1`` = unused slot."""

    def view_jacobian(self, p: np.ndarray) -> np.ndarray | None:
        """(V, 6, q) d(twist [v; w] of T_cam_world)/dp, or None for finite differences."""


class _LocalPoseBlock:
    """Poses ``T = [Rot(w) R0 | t0 + v]`` parameterised by ``[w, v]`` around references ``T0``;
    optionally the translation of some poses is constrained to ``|t| = |t0|`` (2 parameters)."""

    @staticmethod
    def evaluate(T0: np.ndarray, w: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R = _rot(w) @ T0[:, :3, :3]
        t = T0[:, :3, 3] + v
        Jl = so3_left_jacobian(w)
        J = np.zeros((len(T0), 6, 6))
        J[:, :3, :3] = skew(t) @ Jl  # dv from dw (translation is not rotated with the pose)
        J[:, :3, 3:] = np.eye(3)
        J[:, 3:, :3] = Jl
        return make_pose(R, t), J


class FreePoses:
    """One independent pose per view.

    Gauge: view ``ref_view`` is fixed at the identity (no parameters) and the translation of
    ``scale_view`` keeps its initial norm (2 parameters: a direction), i.e. the distance between
    the two camera centres is fixed (1 after :func:`calib.selfcal_init` normalisation). Views with
    ``registered == False`` have no parameters and NaN poses.
    Parameter layout: for each registered non-reference view in order, ``[w (3), v (3)]`` (or
    ``[w (3), a, b]`` for ``scale_view``).
    """

    def __init__(
        self, T0_cam_world: np.ndarray, registered: np.ndarray, ref_view: int, scale_view: int
    ):
        T0 = np.asarray(T0_cam_world, dtype=float).copy()
        reg = np.asarray(registered, dtype=bool).copy()
        if not (reg[ref_view] and reg[scale_view]) or ref_view == scale_view:
            raise ValueError("ref_view and scale_view must be two distinct registered views")
        if not np.allclose(T0[ref_view], np.eye(4), atol=1e-9):
            raise ValueError("the reference view's initial pose must be the identity (gauge)")
        self.T0 = T0
        self.registered = reg
        self.ref_view, self.scale_view = int(ref_view), int(scale_view)
        self.n_views = len(T0)
        self.t_norm = float(np.linalg.norm(T0[scale_view, :3, 3]))
        if self.t_norm <= 0:
            raise ValueError("scale_view coincides with ref_view: zero baseline")
        self.basis = _tangent_basis(T0[scale_view, :3, 3] / self.t_norm)
        cols = -np.ones((self.n_views, 6), dtype=np.int64)
        start = 0
        for v in range(self.n_views):
            if not reg[v] or v == ref_view:
                continue
            n = 5 if v == scale_view else 6
            cols[v, :n] = np.arange(start, start + n)
            start += n
        self._cols = cols
        self.n_params = start

    def initial_params(self) -> np.ndarray:
        return np.zeros(self.n_params)

    def view_columns(self) -> np.ndarray:
        return self._cols

    def _split(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        idx = np.flatnonzero(self._cols[:, 0] >= 0)
        w = np.zeros((len(idx), 3))
        v = np.zeros((len(idx), 3))
        dv_dab = np.zeros((len(idx), 3, 2))
        for j, view in enumerate(idx):
            c = self._cols[view]
            w[j] = p[c[:3]]
            if view == self.scale_view:
                s = self.T0[view, :3, 3] + self.basis @ p[c[3:5]] * self.t_norm
                ns = np.linalg.norm(s)
                t = s / ns * self.t_norm
                v[j] = t - self.T0[view, :3, 3]
                u = t / self.t_norm
                dv_dab[j] = (np.eye(3) - np.outer(u, u)) / ns * self.t_norm**2 @ self.basis
            else:
                v[j] = p[c[3:6]]
        return idx, w, v, dv_dab

    def poses(self, p: np.ndarray) -> np.ndarray:
        T = np.full((self.n_views, 4, 4), np.nan)
        T[self.ref_view] = np.eye(4)
        idx, w, v, _ = self._split(p)
        T[idx], _ = _LocalPoseBlock.evaluate(self.T0[idx], w, v)
        return T

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        J = np.zeros((self.n_views, 6, 6))
        idx, w, v, dv_dab = self._split(p)
        _, Jl = _LocalPoseBlock.evaluate(self.T0[idx], w, v)
        J[idx] = Jl
        s = np.flatnonzero(idx == self.scale_view)[0]
        J[self.scale_view, :, 3:] = 0.0
        J[self.scale_view, :3, 3:5] = dv_dab[s]
        return J


class RigPoses:
    """Stereo-rig poses: per configuration the left camera pose ``T_left_world``, and one shared
    rig transform ``T_right_left`` (left-camera coordinates -> right-camera coordinates), so that
    ``T_right_world = T_right_left @ T_left_world``.

    Gauge: the left camera of configuration ``ref_config`` is the identity (the world frame) and
    ``|t(T_right_left)|`` (the stereo baseline) keeps its initial value. Configurations with
    ``registered == False`` have no parameters and NaN poses.
    Parameter layout: for each registered non-reference configuration ``[w (3), v (3)]`` of the
    left camera, then the rig ``[w (3), a, b]`` (rotation, translation direction).
    """

    def __init__(
        self,
        T0_left_world: np.ndarray,
        T0_right_left: np.ndarray,
        registered: np.ndarray,
        ref_config: int,
    ):
        T0 = np.asarray(T0_left_world, dtype=float).copy()
        reg = np.asarray(registered, dtype=bool).copy()
        if not reg[ref_config]:
            raise ValueError("ref_config must be registered")
        if not np.allclose(T0[ref_config], np.eye(4), atol=1e-9):
            raise ValueError("the reference configuration's left pose must be the identity")
        self.T0 = T0
        self.rig0 = np.asarray(T0_right_left, dtype=float).copy()
        self.registered = reg
        self.ref_config = int(ref_config)
        self.n_configs = len(T0)
        self.n_views = 2 * self.n_configs
        self.baseline = float(np.linalg.norm(self.rig0[:3, 3]))
        if self.baseline <= 0:
            raise ValueError("the rig baseline must be non-zero")
        self.basis = _tangent_basis(self.rig0[:3, 3] / self.baseline)
        self.cfg_idx = np.flatnonzero(reg & (np.arange(self.n_configs) != ref_config))
        self.n_params = 6 * len(self.cfg_idx) + 5
        self.rig_cols = np.arange(6 * len(self.cfg_idx), self.n_params)
        cols = -np.ones((self.n_views, 11), dtype=np.int64)
        for j, c in enumerate(self.cfg_idx):
            cols[2 * c, :6] = np.arange(6 * j, 6 * j + 6)
            cols[2 * c + 1, :6] = np.arange(6 * j, 6 * j + 6)
        for c in np.flatnonzero(reg):
            cols[2 * c + 1, 6:] = self.rig_cols
        self._cols = cols

    def initial_params(self) -> np.ndarray:
        return np.zeros(self.n_params)

    def view_columns(self) -> np.ndarray:
        return self._cols

    def _rig(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q = p[self.rig_cols]
        s = self.rig0[:3, 3] + self.basis @ q[3:5] * self.baseline
        ns = np.linalg.norm(s)
        t = s / ns * self.baseline
        u = t / self.baseline
        T, J = _LocalPoseBlock.evaluate(self.rig0[None], q[None, :3], (t - self.rig0[:3, 3])[None])
        Jr = J[0].copy()
        Jr[:, 3:] = 0.0
        Jr[:3, 3:5] = (np.eye(3) - np.outer(u, u)) / ns * self.baseline**2 @ self.basis
        return T[0], Jr[:, :5]

    def _left(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        TL = np.full((self.n_configs, 4, 4), np.nan)
        JL = np.zeros((self.n_configs, 6, 6))
        TL[self.ref_config] = np.eye(4)
        q = p[: 6 * len(self.cfg_idx)].reshape(-1, 6)
        TL[self.cfg_idx], JL[self.cfg_idx] = _LocalPoseBlock.evaluate(
            self.T0[self.cfg_idx], q[:, :3], q[:, 3:]
        )
        return TL, JL

    def rig(self, p: np.ndarray) -> np.ndarray:
        """``T_right_left`` (4, 4) for parameters ``p``."""
        return self._rig(p)[0]

    def poses(self, p: np.ndarray) -> np.ndarray:
        TL, _ = self._left(p)
        T = np.empty((self.n_views, 4, 4))
        T[0::2] = TL
        T[1::2] = self._rig(p)[0] @ TL
        return T

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        _, JL = self._left(p)
        Trig, Jrig = self._rig(p)
        J = np.zeros((self.n_views, 6, 11))
        J[0::2, :, :6] = JL
        J[1::2, :, :6] = adjoint(Trig) @ JL
        J[1::2, :, 6:] = Jrig
        J[1::2][~self.registered] = 0.0
        return J


# ------------------------------------------------------------------------ residual machinery
def projection_blocks(
    fx: float, mu: float, T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jacobian blocks of the pixel projection for rows (view, point index), OpenCV model:
    w.r.t. ``(fx, mu)`` (k, 2, 2), w.r.t. a camera-frame twist ``[v; w]`` of ``T_cam_world``
    (k, 2, 6) and w.r.t. the world point (k, 2, 3); px per unit."""
    R = T_cam_world[view, :3, :3]
    Xc = np.einsum("kij,kj->ki", R, X[pidx]) + T_cam_world[view, :3, 3]
    xx, yy, z = Xc[:, 0], Xc[:, 1], Xc[:, 2]
    k = len(Xc)
    A = np.zeros((k, 2, 3))
    A[:, 0, 0] = fx / z
    A[:, 0, 2] = -fx * xx / z**2
    A[:, 1, 1] = mu * fx / z
    A[:, 1, 2] = -mu * fx * yy / z**2
    Ji = np.zeros((k, 2, 2))
    Ji[:, 0, 0] = xx / z
    Ji[:, 1, 0] = mu * yy / z
    Ji[:, 1, 1] = fx * yy / z
    D = np.concatenate([np.broadcast_to(np.eye(3), (k, 3, 3)), -skew(Xc)], axis=2)
    return Ji, A @ D, A @ R


def reprojection_residuals(
    fx: float,
    mu: float,
    cx: float,
    cy: float,
    T_cam_world: np.ndarray,
    X: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals ``projected - observed`` (k, 2) px and depths (k,) for rows (view, point index)."""
    R = T_cam_world[view, :3, :3]
    Xc = np.einsum("kij,kj->ki", R, X[pidx]) + T_cam_world[view, :3, 3]
    z = Xc[:, 2]
    r = np.empty((len(view), 2))
    r[:, 0] = fx * Xc[:, 0] / z + cx - uv[:, 0]
    r[:, 1] = mu * fx * Xc[:, 1] / z + cy - uv[:, 1]
    return r, z


@dataclass
class BundleResult:
    """Output of :func:`bundle_adjust` (in the pose model's gauge)."""

    fx: float
    mu: float
    pose_params: np.ndarray
    T_cam_world: np.ndarray  # (V, 4, 4)
    X: np.ndarray  # (P, 3)
    residuals: np.ndarray  # (k, 2) px for the rows passed in
    cost: float
    nfev: int
    status: int
    message: str
    jac: sp.csr_matrix | None = field(default=None, repr=False)
    n_intrinsics: int = 2


class _Problem:
    def __init__(self, model, view, pidx, uv, n_points, cx, cy, fixed_fx_mu):
        self.model = model
        self.view = np.asarray(view, dtype=np.int64)
        self.pidx = np.asarray(pidx, dtype=np.int64)
        self.uv = np.asarray(uv, dtype=float)
        self.n_points = int(n_points)
        self.cx, self.cy = float(cx), float(cy)
        self.fixed = fixed_fx_mu
        self.ni = 0 if fixed_fx_mu is not None else 2
        self.np_ = model.n_params
        self.cols = model.view_columns()
        self.n = self.ni + self.np_ + 3 * self.n_points
        k = len(self.view)
        # column indices of every Jacobian entry: (k, ni + q + 3)
        ccols = np.concatenate(
            [
                np.broadcast_to(np.arange(self.ni), (k, self.ni)),
                np.where(self.cols[self.view] >= 0, self.cols[self.view] + self.ni, -1),
                self.ni + self.np_ + 3 * self.pidx[:, None] + np.arange(3),
            ],
            axis=1,
        )
        self.valid = ccols >= 0
        rows = np.broadcast_to(
            2 * np.arange(k)[:, None, None] + np.arange(2)[None, :, None], (k, 2, ccols.shape[1])
        )
        cc = np.broadcast_to(ccols[:, None, :], rows.shape)
        m = np.broadcast_to(self.valid[:, None, :], rows.shape)
        self.jrows, self.jcols, self.jmask = rows[m], cc[m], m
        self.n_o = self.ni + self.np_  # intrinsics + pose columns; the points follow
        self.ocols = ccols[:, :-3]

    def unpack(self, x):
        if self.fixed is None:
            fx, mu = x[0], x[1]
        else:
            fx, mu = self.fixed
        p = x[self.ni : self.ni + self.np_]
        X = x[self.ni + self.np_ :].reshape(-1, 3)
        return fx, mu, p, X

    def sparsity(self) -> sp.csr_matrix:
        data = np.ones(len(self.jrows))
        return sp.csr_matrix((data, (self.jrows, self.jcols)), shape=(2 * len(self.view), self.n))

    def fun(self, x):
        fx, mu, p, X = self.unpack(x)
        T = self.model.poses(p)
        r, _ = reprojection_residuals(fx, mu, self.cx, self.cy, T, X, self.view, self.pidx, self.uv)
        return r.ravel()

    def blocks(self, x):
        """Jacobian blocks per observation: intrinsics + pose columns ``self.ocols`` (k, 2, c)
        and the point block (k, 2, 3)."""
        fx, mu, p, X = self.unpack(x)
        T = self.model.poses(p)
        Jv = self.model.view_jacobian(p)
        Ji, Jt, Jx = projection_blocks(fx, mu, T, X, self.view, self.pidx)
        Jp = Jt @ Jv[self.view]
        return (np.concatenate([Ji, Jp], axis=2) if self.ni else Jp), Jx

    def jac(self, x):
        Jo, Jx = self.blocks(x)
        data = np.concatenate([Jo, Jx], axis=2)[self.jmask]
        return sp.csr_matrix((data, (self.jrows, self.jcols)), shape=(2 * len(self.view), self.n))

    def normal_equations(self, x, w, r):
        """``J^T W J`` and ``J^T W r`` for per-observation weights ``w`` (k,) and residuals
        ``r`` (k, 2): dense (n, n) up to ``_DENSE_MAX`` unknowns, else sparse."""
        if self.n > _DENSE_MAX:
            J = self.jac(x)
            JtW = (J.T @ sp.diags(np.repeat(w, 2))).tocsr()
            return (JtW @ J).tocsc(), JtW @ r.ravel()
        Jo, Jx = self.blocks(x)
        return dense_normal_equations(Jo, self.ocols, Jx, self.pidx, self.n_o, self.n_points, w, r)


_DENSE_MAX = 1500
"""Unknowns up to which the normal equations are formed and factored densely (LU); larger
problems use sparse matrices and SuperLU."""


def dense_normal_equations(
    Jo: np.ndarray,
    ocols: np.ndarray,
    Jx: np.ndarray,
    pidx: np.ndarray,
    n_o: int,
    n_points: int,
    w: np.ndarray,
    r: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Dense ``A = J^T W J`` (n, n) and ``g = J^T W r`` for a Jacobian whose two rows per
    observation hold ``Jo`` (k, 2, c) in the columns ``ocols`` (k, c) (``-1`` = unused) of the
    first ``n_o`` (global) unknowns and ``Jx`` (k, 2, 3) in the columns ``n_o + 3 pidx + (0..2)``
    of the point; ``w`` (k,) per-observation weights, ``r`` (k, 2) residuals. The same numbers
    as the sparse product, with dense BLAS for the global block and bincounts for the rest."""
    k, _, c = Jo.shape
    P = int(n_points)
    n = n_o + 3 * P
    oc = np.where(ocols >= 0, ocols, n_o)  # unused slots -> a dummy column, dropped below
    A = np.zeros((n, n))
    wJo = Jo * w[:, None, None]
    if n_o * n_o > 50 * c * c:  # few global columns per observation: scatter the local blocks
        L = np.matmul(wJo.transpose(0, 2, 1), Jo)
        idx = oc[:, :, None] * (n_o + 1) + oc[:, None, :]
        Aoo = np.bincount(idx.ravel(), L.ravel(), minlength=(n_o + 1) ** 2)
        A[:n_o, :n_o] = Aoo.reshape(n_o + 1, n_o + 1)[:n_o, :n_o]
        go = np.bincount(oc.ravel(), np.einsum("kra,kr->ka", wJo, r).ravel(), minlength=n_o + 1)
    else:  # observations share most global columns (kinematic chain): dense product
        D = np.zeros((k, 2, n_o + 1))
        D[np.arange(k)[:, None, None], np.arange(2)[None, :, None], oc[:, None, :]] = Jo
        D = D.reshape(2 * k, n_o + 1)[:, :n_o]
        WD = D * np.repeat(w, 2)[:, None]
        A[:n_o, :n_o] = WD.T @ D
        go = WD.T @ r.ravel()
    wJx = Jx * w[:, None, None]
    C = np.matmul(Jo.transpose(0, 2, 1), wJx)  # (k, c, 3)
    idx = (oc[:, :, None] * P + pidx[:, None, None]) * 3 + np.arange(3)
    Aox = np.bincount(idx.ravel(), C.ravel(), minlength=(n_o + 1) * P * 3)
    Aox = Aox.reshape(n_o + 1, 3 * P)[:n_o]
    A[:n_o, n_o:] = Aox
    A[n_o:, :n_o] = Aox.T
    Xb = np.matmul(Jx.transpose(0, 2, 1), wJx)  # (k, 3, 3)
    Axx = np.bincount(
        (pidx[:, None] * 9 + np.arange(9)).ravel(), Xb.ravel(), minlength=9 * P
    ).reshape(P, 3, 3)
    blk = n_o + 3 * np.arange(P)[:, None] + np.arange(3)
    A[blk[:, :, None], blk[:, None, :]] = Axx
    g = np.empty(n)
    g[:n_o] = go[:n_o]
    g[n_o:] = np.bincount(
        (3 * pidx[:, None] + np.arange(3)).ravel(),
        np.einsum("kra,kr->ka", wJx, r).ravel(),
        minlength=3 * P,
    )
    return A, g


class DampedSolver:
    """Solves ``(S A S + lam I) y = S g`` for the Marquardt-scaled normal equations
    (``S = diag(A)^-1/2``) and returns ``x = S y``: dense LU for an ndarray ``A``, SuperLU
    (COLAMD) for a sparse one. Raises ``RuntimeError`` when the damped matrix is singular."""

    def __init__(self, A):
        self.dense = isinstance(A, np.ndarray)
        diag = np.diag(A) if self.dense else A.diagonal()
        d = np.maximum(diag, 1e-12 * max(diag.max(), 1e-300))
        self.s = 1.0 / np.sqrt(d)
        if self.dense:
            self.As = A * self.s[:, None] * self.s[None, :]
        else:
            S = sp.diags(self.s)
            self.As = (S @ A @ S).tocsc()

    def solve(self, g: np.ndarray, lam: float) -> np.ndarray:
        gs = self.s * g
        if self.dense:
            M = self.As.copy()
            M[np.diag_indices_from(M)] += lam
            try:
                y = np.linalg.solve(M, gs)
            except np.linalg.LinAlgError as exc:
                raise RuntimeError(str(exc)) from None
            if not np.isfinite(y).all():
                raise RuntimeError("singular damped normal equations")
            return self.s * y
        lu = splu((self.As + lam * sp.eye(len(gs), format="csc")).tocsc(), permc_spec="COLAMD")
        return self.s * lu.solve(gs)


def _loss_weights(e2: np.ndarray, loss: str, f: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-observation cost ``f^2 rho(e2 / f^2)`` (with the 1/2 folded in by the caller) and IRLS
    weights ``rho'`` for squared residual norms ``e2``."""
    z = e2 / f**2
    if loss == "linear":
        return e2, np.ones_like(e2)
    if loss == "soft_l1":
        return f**2 * 2.0 * (np.sqrt(1.0 + z) - 1.0), 1.0 / np.sqrt(1.0 + z)
    if loss == "huber":
        return f**2 * np.where(z <= 1, z, 2.0 * np.sqrt(z) - 1.0), np.where(
            z <= 1, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300))
        )
    if loss == "cauchy":
        return f**2 * np.log1p(z), 1.0 / (1.0 + z)
    raise ValueError(f"unknown loss {loss!r}; use linear, soft_l1, huber or cauchy")


def _levenberg_marquardt(prob, x0, loss, f_scale, max_nfev, tol):
    """Levenberg-Marquardt (Nielsen damping, Marquardt diagonal scaling) with exact solves of the
    normal equations (dense LU, or SuperLU with COLAMD ordering for large problems). Robust losses are applied to each
    observation's 2-D residual norm by iteratively reweighted least squares."""
    x = np.asarray(x0, dtype=float).copy()
    r = prob.fun(x).reshape(-1, 2)
    nfev = 1
    cost = 0.5 * _loss_weights(np.sum(r**2, axis=1), loss, f_scale)[0].sum()
    lam, nu = 1e-4, 2.0
    status, message = 0, "maximum number of function evaluations reached"
    while nfev < max_nfev:
        w = _loss_weights(np.sum(r**2, axis=1), loss, f_scale)[1]
        A, g = prob.normal_equations(x, w, r)
        if np.max(np.abs(g)) * np.sqrt(len(x)) <= tol * max(cost, 1e-300) ** 0.5 * 1e-3:
            status, message = 1, "gradient tolerance reached"
            break
        solver = DampedSolver(A)
        improved = False
        while nfev < max_nfev:
            try:
                step = -solver.solve(g, lam)
            except RuntimeError:  # singular: damp more
                lam *= nu
                nu *= 2
                continue
            x_new = x + step
            r_new = prob.fun(x_new).reshape(-1, 2)
            nfev += 1
            if not np.isfinite(r_new).all():
                lam *= nu
                nu *= 2
                continue
            cost_new = 0.5 * _loss_weights(np.sum(r_new**2, axis=1), loss, f_scale)[0].sum()
            predicted = -(g @ step) - 0.5 * step @ (A @ step)
            rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
            if rho > 0:
                small_step = np.linalg.norm(step) <= tol * (np.linalg.norm(x) + tol)
                small_cost = cost - cost_new <= tol * cost
                x, r, cost = x_new, r_new, cost_new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                improved = True
                if small_step or small_cost or cost <= 1e-30:
                    status, message = 2, "cost/step tolerance reached"
                break
            lam *= nu
            nu *= 2
            if lam > 1e16:
                status, message = 3, "no further decrease possible (damping saturated)"
                break
        if status:
            break
        if not improved:
            break
    return x, r, float(cost), nfev, status, message


def bundle_adjust(
    model: PoseModel,
    p0: np.ndarray,
    X0: np.ndarray,
    view: np.ndarray,
    pidx: np.ndarray,
    uv: np.ndarray,
    fx0: float,
    mu0: float,
    cx: float,
    cy: float,
    *,
    fix_intrinsics: bool = False,
    loss: str = "soft_l1",
    f_scale_px: float = 1.0,
    max_nfev: int = 100,
    tol: float = 1e-12,
    solver: str = "lm",
) -> BundleResult:
    """Sparse bundle adjustment of ``fx, mu`` (unless fixed), the pose-model parameters and the
    points ``X`` (P, 3).

    Rows are observations ``(view, pidx, uv)``; every view used must have a pose in ``model``.
    ``solver="lm"`` (default): Levenberg-Marquardt with exact normal-equation solves (dense up to
    ``_DENSE_MAX`` unknowns, else sparse) and
    the analytic Jacobian; robust ``loss`` (linear, soft_l1, huber, cauchy; scale ``f_scale_px``)
    on each observation's 2-D residual norm. ``solver="scipy"``:
    :func:`scipy.optimize.least_squares` (trf + lsmr, loss per coordinate), with the analytic
    Jacobian or -- when ``model.view_jacobian`` returns None -- finite differences restricted by
    ``jac_sparsity``. Cost per iteration grows about linearly with the number of observations
    (the dense part of the factorisation is the points + global parameters block).
    """
    fixed = (float(fx0), float(mu0)) if fix_intrinsics else None
    prob = _Problem(model, view, pidx, uv, len(X0), cx, cy, fixed)
    x0 = np.concatenate([[] if fix_intrinsics else [fx0, mu0], p0, np.asarray(X0).ravel()])
    use_analytic = model.view_jacobian(p0) is not None
    if solver == "lm" and use_analytic:
        x, r, cost, nfev, status, message = _levenberg_marquardt(
            prob, x0, loss, f_scale_px, max_nfev, tol
        )
    elif solver in ("lm", "scipy"):
        from scipy.optimize import least_squares  # only this path needs it (import costs 0.2 s)

        kw = (
            dict(jac=prob.jac)
            if use_analytic
            else dict(jac="2-point", jac_sparsity=prob.sparsity())
        )
        res = least_squares(
            prob.fun,
            x0,
            method="trf",
            tr_solver="lsmr",
            x_scale="jac",
            loss=loss,
            f_scale=f_scale_px,
            ftol=tol,
            xtol=tol,
            gtol=tol,
            max_nfev=max_nfev,
            tr_options={"atol": 1e-10, "btol": 1e-10},
            **kw,
        )
        x, r, cost, nfev = res.x, res.fun.reshape(-1, 2), float(res.cost), int(res.nfev)
        status, message = int(res.status), str(res.message)
    else:
        raise ValueError(f"solver must be 'lm' or 'scipy', got {solver!r}")
    fx, mu, p, X = prob.unpack(x)
    T = model.poses(p)
    J = prob.jac(x) if use_analytic else None
    return BundleResult(
        float(fx), float(mu), p.copy(), T, X.copy(), r, cost, nfev, status, message, J, prob.ni
    )


def intrinsics_covariance(J: sp.csr_matrix, residuals: np.ndarray, n_intrinsics: int = 2):
    """Covariance of the first ``n_intrinsics`` parameters ``(fx, mu)`` from the Jacobian:
    ``sigma^2 (J^T J)^-1`` with ``sigma^2 = |r|^2 / (rows - cols)``.

    Returns ``(cov (2, 2), cov_unit (2, 2))`` where ``cov_unit`` assumes 1 px noise per coordinate
    (a purely geometric measure of how well the views determine fx and mu).
    """
    JtJ = (J.T @ J).tocsc()
    n = JtJ.shape[0]
    dof = max(J.shape[0] - n, 1)
    sigma2 = float(np.sum(np.asarray(residuals) ** 2) / dof)
    diag = np.sqrt(np.maximum(JtJ.diagonal(), 1e-300))
    Dinv = sp.diags(1.0 / diag)
    lu = splu((Dinv @ JtJ @ Dinv).tocsc())
    e = np.zeros((n, n_intrinsics))
    e[np.arange(n_intrinsics), np.arange(n_intrinsics)] = 1.0
    sol = lu.solve(e) / diag[:, None]
    cov_unit = sol[:n_intrinsics] / diag[None, :n_intrinsics]
    cov_unit = 0.5 * (cov_unit + cov_unit.T)
    return sigma2 * cov_unit, cov_unit
