"""Camera pose models for the reprojection residuals: where the pose of every view comes from.

The bundle adjustment never sees per-view pose parameters directly: it asks a *pose model*
(:class:`PoseModel`) for ``poses(p) -> T_cam_world (V, 4, 4)``, for the parameter columns each view
depends on (``view_columns() -> (V, q)`` int, ``-1`` = unused slot) and, optionally, for the
derivative of each view pose as a left-perturbation twist in the camera frame
(``view_jacobian(p) -> (V, 6, q)``, twist order ``[v; w]`` as in :mod:`selfcal.transforms`): a change
``dp`` moves camera coordinates by ``dXc = dv + dw x Xc`` with ``[dv; dw] = J_v dp``.
:class:`FreePoses` (one 6-dof pose per view) and :class:`RigPoses` (one pose per configuration plus
a shared transform per further camera of the rig) are the two models provided here; the kinematic
chain (:class:`selfcal.estimation.kinematic_poses.KinematicPoses`) implements the same methods. If
``view_jacobian`` returns ``None`` the adjustment falls back to finite differences restricted by
``jac_sparsity``. The pose model also owns the gauge: the models here fix one camera at the identity
and one baseline length to 1. ``param_instances()`` (optional) labels the parameters
that belong to one configuration or view only, so the solver can eliminate them (Schur).

Frames: ``T_cam_world`` maps world coordinates to the OpenCV camera frame; views are indexed by
:class:`selfcal.estimation.observations.ViewLayout` (the cameras of configuration 0, then of 1, ...).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from selfcal.errors import UsageError
from selfcal.estimation.observations import ViewLayout
from selfcal.transforms import adjoint, make_pose, matrix_from_rotvec, skew

__all__ = ["so3_left_jacobian", "PoseModel", "FreePoses", "ViewPoses", "RigPoses"]


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
    return matrix_from_rotvec(np.asarray(w, dtype=float).reshape(-1, 3))


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
    the two camera centres is fixed (1 after :func:`selfcal.calibration.field.adjust.gauge`). Views with
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
            raise UsageError("ref_view and scale_view must be two distinct registered views")
        if not np.allclose(T0[ref_view], np.eye(4), atol=1e-9):
            raise UsageError("the reference view's initial pose must be the identity (gauge)")
        self.T0 = T0
        self.registered = reg
        self.ref_view, self.scale_view = int(ref_view), int(scale_view)
        self.n_views = len(T0)
        self.t_norm = float(np.linalg.norm(T0[scale_view, :3, 3]))
        if self.t_norm <= 0:
            raise UsageError("scale_view coincides with ref_view: zero baseline")
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

    def param_instances(self) -> np.ndarray:
        """(n_params,) the view each parameter belongs to (every parameter is one view's)."""
        inst = np.empty(self.n_params, np.int64)
        rows, slots = np.nonzero(self._cols >= 0)
        inst[self._cols[rows, slots]] = rows
        return inst

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


class ViewPoses:
    """One independent pose per registered view and no gauge: the world frame and the scale are
    fixed by something else, e.g. the known points of a board (its frame is the world).
    Parameter layout: ``[w (3), v (3)]`` of each registered view in order; views with
    ``registered == False`` have no parameters and NaN poses."""

    def __init__(self, T0_cam_world: np.ndarray, registered: np.ndarray):
        self.T0 = np.asarray(T0_cam_world, dtype=float).copy()
        self.registered = np.asarray(registered, dtype=bool).copy()
        self.n_views = len(self.T0)
        idx = np.flatnonzero(self.registered)
        cols = -np.ones((self.n_views, 6), dtype=np.int64)
        cols[idx] = 6 * np.arange(len(idx))[:, None] + np.arange(6)
        self._idx, self._cols = idx, cols
        self.n_params = 6 * len(idx)

    def initial_params(self) -> np.ndarray:
        return np.zeros(self.n_params)

    def view_columns(self) -> np.ndarray:
        return self._cols

    def param_instances(self) -> np.ndarray:
        """(n_params,) the view each parameter belongs to."""
        return np.repeat(self._idx, 6)

    def _evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        wv = np.asarray(p, dtype=float).reshape(-1, 6)
        return _LocalPoseBlock.evaluate(self.T0[self._idx], wv[:, :3], wv[:, 3:])

    def poses(self, p: np.ndarray) -> np.ndarray:
        T = np.full((self.n_views, 4, 4), np.nan)
        T[self._idx] = self._evaluate(p)[0]
        return T

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        J = np.zeros((self.n_views, 6, 6))
        J[self._idx] = self._evaluate(p)[1]
        return J


class RigPoses:
    """Rig poses: per configuration the first camera's pose ``T_first_world``, and one shared
    transform per further camera ``T_cam_first`` (first-camera coordinates -> camera ``c``), so
    that ``T_cam_world = T_cam_first @ T_first_world``. The stereo pair: first = left, one
    transform ``T_right_left``.

    Gauge: the first camera of configuration ``ref_config`` is the identity (the world frame) and
    ``|t(T_cam_first)|`` of the second camera (the stereo baseline) keeps its initial value.
    Configurations with ``registered == False`` have no parameters and NaN poses.
    Parameter layout: for each registered non-reference configuration ``[w (3), v (3)]`` of the
    first camera, then the second camera's ``[w (3), a, b]`` (rotation, translation direction),
    then ``[w (3), v (3)]`` of each further camera.
    """

    def __init__(
        self,
        T0_first_world: np.ndarray,
        T0_cam_first: np.ndarray,
        registered: np.ndarray,
        ref_config: int,
    ):
        T0 = np.asarray(T0_first_world, dtype=float).copy()
        reg = np.asarray(registered, dtype=bool).copy()
        if not reg[ref_config]:
            raise UsageError("ref_config must be registered")
        if not np.allclose(T0[ref_config], np.eye(4), atol=1e-9):
            raise UsageError("the reference configuration's first pose must be the identity")
        self.T0 = T0
        self.rigs0 = np.asarray(T0_cam_first, dtype=float).reshape(-1, 4, 4).copy()
        if len(self.rigs0) == 0:
            raise UsageError(
                "a rig pose model needs at least two cameras (the baseline fixes the scale); "
                "for one camera use FreePoses"
            )
        self.registered = reg
        self.ref_config = int(ref_config)
        self.n_configs = len(T0)
        self.layout = ViewLayout(self.n_configs, 1 + len(self.rigs0))
        self.n_views = self.layout.n_views
        self.baseline = float(np.linalg.norm(self.rigs0[0, :3, 3]))
        if self.baseline <= 0:
            raise UsageError("the rig baseline must be non-zero")
        self.basis = _tangent_basis(self.rigs0[0, :3, 3] / self.baseline)
        self.cfg_idx = np.flatnonzero(reg & (np.arange(self.n_configs) != ref_config))
        start = 6 * len(self.cfg_idx)
        self.rig_cols_all = []
        for c in range(len(self.rigs0)):
            n = 5 if c == 0 else 6
            self.rig_cols_all.append(np.arange(start, start + n))
            start += n
        self.n_params = start
        width = 6 + max(len(rc) for rc in self.rig_cols_all)
        cols = -np.ones((self.n_views, width), dtype=np.int64)
        by = self.layout.by_frame(cols)
        for j, cfg in enumerate(self.cfg_idx):
            by[cfg, :, :6] = np.arange(6 * j, 6 * j + 6)
        for c, rc in enumerate(self.rig_cols_all, start=1):
            by[reg, c, 6 : 6 + len(rc)] = rc
        self._cols = cols

    def initial_params(self) -> np.ndarray:
        return np.zeros(self.n_params)

    def view_columns(self) -> np.ndarray:
        return self._cols

    def param_instances(self) -> np.ndarray:
        """(n_params,) the configuration of each first-camera pose parameter, -1 for the rig."""
        inst = -np.ones(self.n_params, np.int64)
        inst[: 6 * len(self.cfg_idx)] = np.repeat(self.cfg_idx, 6)
        return inst

    def _rig(self, p: np.ndarray, c: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``T_cam_first`` of camera ``c + 1`` and its twist Jacobian (6, params)."""
        q = p[self.rig_cols_all[c]]
        rig0 = self.rigs0[c]
        if c > 0:
            T, J = _LocalPoseBlock.evaluate(rig0[None], q[None, :3], q[None, 3:6])
            return T[0], J[0]
        s = rig0[:3, 3] + self.basis @ q[3:5] * self.baseline
        ns = np.linalg.norm(s)
        t = s / ns * self.baseline
        u = t / self.baseline
        T, J = _LocalPoseBlock.evaluate(rig0[None], q[None, :3], (t - rig0[:3, 3])[None])
        Jr = J[0].copy()
        Jr[:, 3:] = 0.0
        Jr[:3, 3:5] = (np.eye(3) - np.outer(u, u)) / ns * self.baseline**2 @ self.basis
        return T[0], Jr[:, :5]

    def _first(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        TL = np.full((self.n_configs, 4, 4), np.nan)
        JL = np.zeros((self.n_configs, 6, 6))
        TL[self.ref_config] = np.eye(4)
        q = p[: 6 * len(self.cfg_idx)].reshape(-1, 6)
        TL[self.cfg_idx], JL[self.cfg_idx] = _LocalPoseBlock.evaluate(
            self.T0[self.cfg_idx], q[:, :3], q[:, 3:]
        )
        return TL, JL

    def rig(self, p: np.ndarray) -> np.ndarray:
        """``T_cam_first`` (4, 4) of the second camera (stereo: ``T_right_left``)."""
        return self._rig(p)[0]

    def rigs(self, p: np.ndarray) -> np.ndarray:
        """``T_cam_first`` (N - 1, 4, 4) of every further camera."""
        return np.stack([self._rig(p, c)[0] for c in range(len(self.rigs0))])

    def poses(self, p: np.ndarray) -> np.ndarray:
        TL, _ = self._first(p)
        T = np.empty((self.n_views, 4, 4))
        by = self.layout.by_frame(T)
        by[:, 0] = TL
        for c in range(len(self.rigs0)):
            by[:, c + 1] = self._rig(p, c)[0] @ TL
        return T

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        _, JL = self._first(p)
        J = np.zeros((self.n_views, 6, self._cols.shape[1]))
        by = self.layout.by_frame(J)
        by[:, 0, :, :6] = JL
        for c in range(len(self.rigs0)):
            Trig, Jrig = self._rig(p, c)
            by[:, c + 1, :, :6] = adjoint(Trig) @ JL
            by[:, c + 1, :, 6 : 6 + Jrig.shape[1]] = Jrig
            by[~self.registered, c + 1] = 0.0
        return J
