"""One-step maximum-likelihood refinement: kinematics, camera and scene from the pixels directly.

The paper's two-stage method first estimates every camera pose by bundle adjustment and then fits
the kinematic model to those poses with diagonal weights. That discards information: the per-pose
errors are strongly correlated (camera y-translation with rotation about x) and correlated across
poses through the shared 3-D points. Here the camera poses are *not* free: the left camera of
configuration ``i`` is the tool of the MCPC chain, ``T_world_cam_i = fk_tool(model(rho), q_i)``, the
right camera is ``T_world_cam_i @ T_left_right``, and one sparse Levenberg-Marquardt adjustment
minimises the reprojection error over

- ``fx``, ``mu`` (principal point known: the image centre, as in the camera stage),
- the free minimal MCPC parameters ``rho`` (tool = left camera, OpenCV frame),
- the rig ``T_right_left`` (6 parameters: no baseline gauge, the scale comes from ``d``),
- all 3-D marker corners,

plus one *hard* residual ``(|c_a - c_b| - d) / scale_sigma_m`` (in px, i.e. ``d`` known to
``scale_sigma_m`` relative to 1 px of corner noise) for the two scale-marker centres. It starts from
the two-stage result (:mod:`calib.selfcal` + :func:`calib.identify.identify`).

Joint read-back errors (``joint_sigma``): once the poses are tied to the kinematics, the joint
read-back is a measurement too. Encoder quantisation (SCORBOT: 0.002-0.010 deg RMS) moves the
camera by ~0.1-0.2 px, comparable to the per-pose precision of ~40 corners, and an adjustment
that takes ``q`` as exact pushes that misfit into fx, the points and the kinematics (simulation,
noise-free corners, quantised joints: tool tip 0.29 mm instead of the two-stage 0.01 mm).
With ``joint_sigma`` every configuration gets corrections ``dq`` with the Gaussian prior
``dq ~ N(0, joint_sigma^2)`` (errors in variables), which makes the estimate the maximum-
likelihood one for noisy corners *and* noisy read-back (same case: 0.007 mm).

Gauge (:func:`choose_gauge`): with an unknown scene the world frame (6 dof) and the scale are
free. The scale is fixed by the ``d`` residual. The world frame is fixed by holding six MCPC
parameters at their two-stage values: the four base parameters of ``V_0`` (``alpha0, beta0, lx0,
ly0``) and two of ``V_1``. For the SCORBOT (``|alpha1| ~ 90 deg``) a rotation of the world about
joint 1's axis moves exactly ``beta1`` and a shift along that axis exactly ``ly1``
(``Rz(phi) Rx(+-90) = Rx(+-90) Ry(-+phi)``; ``Rx(+-90)^T z = -+y``), so those two are held.
Otherwise the two are chosen by pivoted QR of the gauge directions (the derivative of the minimal
parameters w.r.t. a change of world frame) in the complement of what the base four absorb. The
held set is verified to be transversal to the gauge orbit twice: the 6 x 6 block of the gauge
directions is well conditioned, and the column-scaled Jacobian over all free unknowns (intrinsics,
free MCPC parameters, rig, points) has full column rank at the start
(:class:`JointRefinementError` otherwise). Parameters the two-stage identifiability analysis held
stay held.

Results are reported in the same frame as the two-stage method (world = left camera of the
reference configuration): after the adjustment the model and the points are re-expressed in the
frame of the *refined* reference camera pose, and the parameter covariance is propagated to that
frame (so every minimal parameter gets a standard deviation, like the two-stage report). The
covariance is ``sigma^2 (J^T J)^-1`` of the final least-squares Jacobian restricted to the
kinematic block (points, rig and intrinsics are nuisance parameters, marginalised by the inverse).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from calib.bundle_adjust import (
    _DENSE_MAX,
    DampedSolver,
    Observations,
    dense_normal_equations,
    projection_blocks,
    reprojection_residuals,
    so3_left_jacobian,
)
from calib.errors import EstimationError
from calib.identify import IdentificationResult, express_in_frame, minimal_difference
from calib.kinematics import fk_frames, fk_tool, identification_jacobian
from calib.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names
from calib.transforms import adjoint, inv_pose, make_pose, pose_from_vec, skew

__all__ = [
    "JointRefinementError",
    "KinematicPoses",
    "GaugeChoice",
    "gauge_directions",
    "choose_gauge",
    "JointRefinementResult",
    "joint_refine",
    "tool_point_covariance",
    "encoder_sigma",
    "method_summary",
    "joint_document",
    "refine_calibration",
    "aligned_tool_rms_bound",
]

_RAYLEIGH_MEDIAN = 1.1774  # median of |r| for 2-D Gaussian noise with unit sigma per axis
_BASE_HELD = ("alpha0", "beta0", "lx0", "ly0")
_GAUGE_LENGTH_M = 0.3  # angles are compared with lengths as displacements at this radius


class JointRefinementError(EstimationError):
    """The joint refinement cannot give a trustworthy answer (gauge not fixed, no convergence,
    missing scale markers); the message names the cause and the fix."""


# --------------------------------------------------------------------------------------------
# Pose model
# --------------------------------------------------------------------------------------------


class KinematicPoses:
    """Camera poses from the kinematic chain: a :class:`calib.bundle_adjust.PoseModel`.

    Configuration ``i`` (with ``active[i]``): left camera ``T_world_cam = fk_tool(model(rho), q_i)``
    (the model's tool is the left camera, OpenCV frame), right camera ``T_right_world =
    T_right_left @ T_left_world``. Views ``2 i`` (left) and ``2 i + 1`` (right); inactive
    configurations have NaN poses and no parameters.

    Parameters ``p = [rho_free (k), rig (6)]``: ``rho_free`` the *absolute* values (rad, m) of the
    flat MCPC parameters ``free_idx`` (indices into ``model.params.reshape(-1)``, all others fixed
    at ``model``'s values), ``rig = [w, v]`` the left-perturbation of ``T_right_left`` around
    ``T0_right_left``: ``R = Rot(w) R0``, ``t = t0 + v``.

    With ``joint_corrections=True`` the parameters continue with ``dq`` (n per active
    configuration, rad / m): the poses use ``q_i + dq_i`` (errors in the joint read-back, e.g.
    encoder quantisation; the caller adds a prior on ``dq``). ``dq_cols`` are their indices in ``p``.

    ``view_jacobian`` is analytic: the identification Jacobian is the body twist ``xi`` of
    ``T_world_cam`` (``dT = T xi^``), so ``T_cam_world`` moves by the camera-frame twist ``-xi``
    (the bundle adjustment's convention); the right camera by ``Ad(T_right_left) (-xi)``. The joint
    columns are the joint axes' twists in the tool frame.
    """

    def __init__(
        self,
        model: MCPCModel,
        q: np.ndarray,
        free_idx: np.ndarray,
        T0_right_left: np.ndarray,
        active: np.ndarray | None = None,
        *,
        joint_corrections: bool = False,
    ):
        self.model = model
        self.q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.q.shape[1] != model.n:
            raise ValueError(f"q must have shape (m, {model.n}) (rad), got {self.q.shape}")
        self.free_idx = np.asarray(free_idx, dtype=np.int64)
        if len(np.unique(self.free_idx)) != len(self.free_idx):
            raise ValueError("free_idx contains duplicates")
        self.rig0 = np.asarray(T0_right_left, dtype=float).copy()
        m = len(self.q)
        self.active = np.ones(m, bool) if active is None else np.asarray(active, bool).copy()
        if self.active.shape != (m,):
            raise ValueError(f"active must have shape ({m},)")
        self.n_configs = m
        self.n_views = 2 * m
        self.k = len(self.free_idx)
        act = np.flatnonzero(self.active)
        n = model.n
        self.n_dq = n * len(act) if joint_corrections else 0
        self.dq_cols = self.k + 6 + np.arange(self.n_dq)
        self.n_params = self.k + 6 + self.n_dq
        q_cols = self.k + 6 + (n if joint_corrections else 0)
        cols = -np.ones((self.n_views, q_cols), dtype=np.int64)
        cols[2 * act, : self.k] = np.arange(self.k)
        cols[2 * act + 1, : self.k + 6] = np.arange(self.k + 6)
        if joint_corrections:
            dq = self.dq_cols.reshape(len(act), n)
            cols[2 * act, self.k + 6 :] = dq
            cols[2 * act + 1, self.k + 6 :] = dq
        self._cols = cols
        self._act = act

    def initial_params(self) -> np.ndarray:
        return np.concatenate(
            [self.model.params.reshape(-1)[self.free_idx], np.zeros(6 + self.n_dq)]
        )

    def joints(self, p: np.ndarray) -> np.ndarray:
        """Joint vectors (m_active, n) used for the active configurations (read-back + dq)."""
        q = self.q[self._act]
        if self.n_dq:
            q = q + p[self.dq_cols].reshape(q.shape)
        return q

    def view_columns(self) -> np.ndarray:
        return self._cols

    def kinematic_model(self, p: np.ndarray) -> MCPCModel:
        """The MCPC model for parameters ``p``."""
        flat = self.model.params.reshape(-1).copy()
        flat[self.free_idx] = p[: self.k]
        return self.model.with_params(flat)

    def rig(self, p: np.ndarray) -> np.ndarray:
        """``T_right_left`` (4, 4) for parameters ``p``."""
        w, v = p[self.k : self.k + 3], p[self.k + 3 : self.k + 6]
        return make_pose(
            pose_from_vec(np.r_[w, 0, 0, 0])[:3, :3] @ self.rig0[:3, :3], self.rig0[:3, 3] + v
        )

    def poses(self, p: np.ndarray) -> np.ndarray:
        T = np.full((self.n_views, 4, 4), np.nan)
        act = self._act
        TL = inv_pose(fk_tool(self.kinematic_model(p), self.joints(p)))
        T[2 * act] = TL
        T[2 * act + 1] = self.rig(p) @ TL
        return T

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        q_cols = self._cols.shape[1]
        J = np.zeros((self.n_views, 6, q_cols))
        act = self._act
        mdl = self.kinematic_model(p)
        qa = self.joints(p)
        JL = -identification_jacobian(mdl, qa)[:, :, self.free_idx]
        if self.n_dq:
            F = fk_frames(mdl, qa)
            X = inv_pose(F[:, -1:]) @ F[:, :-1]  # joint frames in the tool frame (m, n, 4, 4)
            w = X[..., :3, 2]
            tw = np.concatenate([np.cross(X[..., :3, 3], w), w], axis=-1)  # revolute
            pris = np.array([t == "prismatic" for t in mdl.joint_types])
            tw[:, pris] = np.concatenate([w[:, pris], 0 * w[:, pris]], axis=-1)
            JL = np.concatenate([JL, np.zeros((len(act), 6, 6)), -np.swapaxes(tw, 1, 2)], axis=2)
        else:
            JL = np.concatenate([JL, np.zeros((len(act), 6, 6))], axis=2)
        Trig = self.rig(p)
        J[2 * act] = JL
        J[2 * act + 1] = adjoint(Trig) @ JL
        w = p[self.k : self.k + 3]
        Jl = so3_left_jacobian(w)
        Jr = np.zeros((6, 6))
        Jr[:3, :3] = skew(Trig[:3, 3]) @ Jl
        Jr[:3, 3:] = np.eye(3)
        Jr[3:, :3] = Jl
        J[2 * act + 1, :, self.k : self.k + 6] = Jr
        return J


# --------------------------------------------------------------------------------------------
# Gauge
# --------------------------------------------------------------------------------------------


def gauge_directions(model: MCPCModel, eps: float = 1e-6) -> np.ndarray:
    """(P, 6): derivative of the minimal parameters (eq. 10 order, SI) w.r.t. a change of world
    frame ``T_new_old = exp([v; w])`` (central differences through :func:`express_in_frame`)."""
    G = np.empty((minimal_indices(model.joint_types).size, 6))
    for j in range(6):
        xi = np.zeros(6)
        xi[j] = eps
        vec = np.r_[xi[3:], xi[:3]]  # pose_from_vec takes [rotvec, translation]
        plus = express_in_frame(model, pose_from_vec(vec), like=model)
        minus = express_in_frame(model, pose_from_vec(-vec), like=model)
        G[:, j] = minimal_difference(plus, minus) / (2 * eps)
    return G


@dataclass(frozen=True)
class GaugeChoice:
    """The six MCPC parameters held to fix the world frame (see the module docstring).

    ``held``: names; ``method``: ``"alpha1-90"`` (beta1, ly1 by the SCORBOT argument) or
    ``"pivoted-qr"``; ``condition_number`` of the (unit-scaled) 6 x 6 block of the gauge
    directions at the held parameters (finite and moderate = transversal to the gauge orbit).
    """

    held: tuple[str, ...]
    method: str
    condition_number: float


def choose_gauge(model: MCPCModel, *, alpha1_tol_deg: float = 10.0) -> GaugeChoice:
    """Choose the six held parameters: ``alpha0, beta0, lx0, ly0`` and two of the rest.

    If ``|alpha1|`` is within ``alpha1_tol_deg`` of 90 deg: ``beta1, ly1``. Otherwise pivoted QR
    on the gauge directions projected onto the complement of what the base four absorb (angles
    scaled by 0.3 m). Raises :class:`JointRefinementError` if the resulting set is not
    transversal to the gauge orbit (condition number > 1e8).
    """
    idx = minimal_indices(model.joint_types)
    names = param_names(idx)
    G = gauge_directions(model)
    scale = np.where(param_is_angle(idx), _GAUGE_LENGTH_M, 1.0)
    Gs = G * scale[:, None]
    Gs[:, 3:] *= _GAUGE_LENGTH_M  # rotations of the world as displacements too
    alpha1 = float(model.params[1, 0])
    base = [names.index(b) for b in _BASE_HELD]
    if abs(abs(np.degrees(alpha1)) - 90.0) <= alpha1_tol_deg:
        extra = [names.index("beta1"), names.index("ly1")]
        method = "alpha1-90"
    else:
        B = Gs[base]  # (4, 6)
        N = scipy.linalg.null_space(B)  # (6, 2) world motions the base four do not see
        rest = [i for i in range(len(names)) if i not in base]
        _, _, piv = scipy.linalg.qr((Gs[rest] @ N).T, pivoting=True)
        extra = [rest[i] for i in piv[:2]]
        method = "pivoted-qr"
    H = Gs[base + extra]
    H = H / np.linalg.norm(H, axis=1, keepdims=True)
    s = np.linalg.svd(H, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if not cond < 1e8:
        raise JointRefinementError(
            f"the held parameters {[names[i] for i in base + extra]} do not fix the world frame "
            f"(gauge block condition number {cond:.3g}); the robot's first two axes are probably "
            "(nearly) parallel -- this gauge choice does not apply"
        )
    return GaugeChoice(tuple(names[i] for i in base + extra), method, cond)


# --------------------------------------------------------------------------------------------
# The least-squares problem
# --------------------------------------------------------------------------------------------


class _Problem:
    """Residuals ``[reprojection (2 k) px; scale (1); priors (E)]`` over ``x = [fx, mu, p,
    X (3 P)]``; the prior rows are ``prior_w * p[prior_cols]`` (zero-mean Gaussian priors)."""

    def __init__(
        self, model, view, pidx, uv, n_points, cx, cy, scale_idx, d_m, w_scale, prior_cols, prior_w
    ):
        self.model = model
        self.view = np.asarray(view, dtype=np.int64)
        self.pidx = np.asarray(pidx, dtype=np.int64)
        self.uv = np.asarray(uv, dtype=float)
        self.n_points = int(n_points)
        self.cx, self.cy = float(cx), float(cy)
        self.sa, self.sb = (np.asarray(s, dtype=np.int64) for s in scale_idx)
        self.d, self.w = float(d_m), float(w_scale)
        self.np_ = model.n_params
        self.cols = model.view_columns()
        self.n = 2 + self.np_ + 3 * self.n_points
        k = len(self.view)
        self.k = k
        pcol = self.cols[self.view]
        ccols = np.concatenate(
            [
                np.broadcast_to(np.arange(2), (k, 2)),
                np.where(pcol >= 0, pcol + 2, -1),
                2 + self.np_ + 3 * self.pidx[:, None] + np.arange(3),
            ],
            axis=1,
        )
        valid = ccols >= 0
        rows = np.broadcast_to(
            2 * np.arange(k)[:, None, None] + np.arange(2)[None, :, None], (k, 2, ccols.shape[1])
        )
        cc = np.broadcast_to(ccols[:, None, :], rows.shape)
        self.jmask = np.broadcast_to(valid[:, None, :], rows.shape)
        srow_cols = 2 + self.np_ + 3 * np.concatenate([self.sa, self.sb])[:, None] + np.arange(3)
        self.prior_cols = np.asarray(prior_cols, dtype=np.int64)
        self.prior_w = np.asarray(prior_w, dtype=float)
        E = len(self.prior_cols)
        self.jrows = np.concatenate(
            [rows[self.jmask], np.full(srow_cols.size, 2 * k), 2 * k + 1 + np.arange(E)]
        )
        self.jcols = np.concatenate([cc[self.jmask], srow_cols.ravel(), 2 + self.prior_cols])
        self.shape = (2 * k + 1 + E, self.n)
        self.n_pix = 2 * k
        self.ocols = ccols[:, :-3]

    def unpack(self, x):
        return x[0], x[1], x[2 : 2 + self.np_], x[2 + self.np_ :].reshape(-1, 3)

    def _scale(self, X):
        u = X[self.sa].mean(axis=0) - X[self.sb].mean(axis=0)
        return float(np.linalg.norm(u)), u

    def fun(self, x):
        fx, mu, p, X = self.unpack(x)
        T = self.model.poses(p)
        r, _ = reprojection_residuals(fx, mu, self.cx, self.cy, T, X, self.view, self.pidx, self.uv)
        dist, _ = self._scale(X)
        return np.concatenate(
            [r.ravel(), [self.w * (dist - self.d)], self.prior_w * p[self.prior_cols]]
        )

    def _blocks(self, x):
        fx, mu, p, X = self.unpack(x)
        T = self.model.poses(p)
        Jv = self.model.view_jacobian(p)
        Ji, Jt, Jx = projection_blocks(fx, mu, T, X, self.view, self.pidx)
        dist, u = self._scale(X)
        g = self.w * u / max(dist, 1e-300)
        sdata = np.concatenate(
            [np.tile(g / len(self.sa), len(self.sa)), np.tile(-g / len(self.sb), len(self.sb))]
        )
        return np.concatenate([Ji, Jt @ Jv[self.view]], axis=2), Jx, sdata

    def jac(self, x):
        Jo, Jx, sdata = self._blocks(x)
        blocks = np.concatenate([Jo, Jx], axis=2)
        data = np.concatenate([blocks[self.jmask], sdata, self.prior_w])
        return sp.csr_matrix((data, (self.jrows, self.jcols)), shape=self.shape)

    def normal_equations(self, x, w, r):
        """``J^T W J`` and ``J^T W r`` with weights ``w`` (k,) on the observations (the scale
        and prior rows unweighted): dense up to ``_DENSE_MAX`` unknowns, else sparse."""
        if self.n > _DENSE_MAX:
            J = self.jac(x)
            wr = np.r_[np.repeat(w, 2), np.ones(self.shape[0] - self.n_pix)]
            JtW = (J.T @ sp.diags(wr)).tocsr()
            return (JtW @ J).tocsc(), JtW @ r
        Jo, Jx, sdata = self._blocks(x)
        k = len(self.view)
        A, g = dense_normal_equations(
            Jo, self.ocols, Jx, self.pidx, 2 + self.np_, self.n_points, w, r[: 2 * k].reshape(k, 2)
        )
        scols = self.jcols[len(self.jcols) - len(self.prior_w) - len(sdata) :][: len(sdata)]
        A[np.ix_(scols, scols)] += np.outer(sdata, sdata)
        g[scols] += sdata * r[2 * k]
        pc = 2 + self.prior_cols
        A[pc, pc] += self.prior_w**2
        g[pc] += self.prior_w * r[2 * k + 1 :]
        return A, g


def _irls(e2: np.ndarray, loss: str, f: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-observation cost (2 x rho) and IRLS weight for squared 2-D residual norms ``e2``."""
    if loss == "linear":
        return e2, np.ones_like(e2)
    if loss == "soft_l1":
        z = e2 / f**2
        return f**2 * 2.0 * (np.sqrt(1.0 + z) - 1.0), 1.0 / np.sqrt(1.0 + z)
    raise ValueError(f"unknown loss {loss!r}; use 'linear' or 'soft_l1'")


def _cost_weights(r: np.ndarray, loss: str, f: float, n_pix: int) -> tuple[float, np.ndarray]:
    rp = r[:n_pix].reshape(-1, 2)
    c, w = _irls(np.sum(rp**2, axis=1), loss, f)
    rest = r[n_pix:]
    return 0.5 * (float(c.sum()) + float(rest @ rest)), np.r_[np.repeat(w, 2), np.ones(len(rest))]


def _levenberg_marquardt(prob, x0, loss, f_scale, max_iter, tol):
    """LM (Nielsen damping, Marquardt scaling), exact sparse normal-equation solves; robust loss
    on each observation's 2-D residual norm by IRLS, the scale row always plain."""
    x = np.asarray(x0, dtype=float).copy()
    r = prob.fun(x)
    cost, _ = _cost_weights(r, loss, f_scale, prob.n_pix)
    lam, nu = 1e-4, 2.0
    it, nfev = 0, 1
    status, message = 0, "maximum number of iterations reached"
    while it < max_iter:
        it += 1
        _, w = _cost_weights(r, loss, f_scale, prob.n_pix)
        A, g = prob.normal_equations(x, w[: prob.n_pix : 2], r)
        solver = DampedSolver(A)
        gs = solver.s * g
        if np.max(np.abs(gs)) <= tol * 1e-3 * max(np.sqrt(2 * cost), 1e-300):
            status, message = 1, "gradient tolerance reached"
            break
        improved = False
        while True:
            try:
                step = -solver.solve(g, lam)
            except RuntimeError:
                lam *= nu
                nu *= 2
                continue
            x_new = x + step
            r_new = prob.fun(x_new)
            nfev += 1
            cost_new = (
                _cost_weights(r_new, loss, f_scale, prob.n_pix)[0]
                if np.isfinite(r_new).all()
                else np.inf
            )
            predicted = -(g @ step) - 0.5 * step @ (A @ step)
            rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
            if rho > 0:
                small = cost - cost_new <= tol * cost or np.linalg.norm(step) <= tol * (
                    np.linalg.norm(x) + tol
                )
                x, r, cost = x_new, r_new, cost_new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                improved = True
                if small:
                    status, message = 2, "cost/step tolerance reached"
                break
            lam *= nu
            nu *= 2
            if lam > 1e16:
                status, message = 3, "no further decrease possible (damping saturated)"
                break
        if status or not improved:
            if not improved and not status:
                status, message = 3, "no further decrease possible"
            break
    return x, r, float(cost), it, nfev, status, message


def _scaled_min_singular(J: sp.csr_matrix) -> tuple[float, int]:
    """Smallest singular value of the unit-column-scaled J and the numerical rank (rtol 1e-9)."""
    JtJ = (J.T @ J).toarray()
    dg = np.sqrt(np.maximum(np.diag(JtJ), 1e-300))
    ev = np.linalg.eigvalsh(JtJ / np.outer(dg, dg))
    s = np.sqrt(np.clip(ev, 0.0, None))[::-1]
    return float(s[-1] / s[0]), int(np.sum(s > 1e-9 * s[0]))


def _inverse_block(J: sp.csr_matrix, cols: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` restricted to ``cols`` (exact sparse solve)."""
    JtJ = (J.T @ J).tocsc()
    dg = np.sqrt(np.maximum(JtJ.diagonal(), 1e-300))
    e = np.zeros((JtJ.shape[0], len(cols)))
    e[cols, np.arange(len(cols))] = 1.0
    if JtJ.shape[0] <= _DENSE_MAX:  # dense LU: faster than SuperLU at this size
        M = JtJ.toarray() / dg[:, None] / dg[None, :]
        sol = np.linalg.solve(M, e / dg[:, None]) / dg[:, None]
    else:
        Dinv = sp.diags(1.0 / dg)
        lu = splu((Dinv @ JtJ @ Dinv).tocsc(), permc_spec="COLAMD")
        sol = lu.solve(e / dg[:, None]) / dg[:, None]
    out = sol[cols]
    return 0.5 * (out + out.T)


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------


@dataclass
class JointRefinementResult:
    """Outcome of :func:`joint_refine`. SI units; world = left camera of ``ref_config``.

    Attributes:
        model: refined MCPC model (tool = left camera), world = the refined reference camera.
        model_gauge: the same chain in the optimisation gauge (held parameters at their
            two-stage values).
        fx, mu, cx, cy: intrinsics (px); ``fx_std``, ``mu_std`` from the final Jacobian.
        T_left_right: rig (right camera in the left camera frame, m).
        T_world_cam: (m, 2, 4, 4) camera poses of all configurations (NaN if not active).
        point_ids, X_world: reconstructed corners (P, 3) m (NaN: not in the adjustment).
        names: the minimal parameter names (eq. 10 order); ``values`` in ``model``;
            ``std``: standard deviations in the reference-camera frame (like the two-stage
            report; nan for parameters held by the identifiability analysis);
        covariance: (P, P) covariance of all minimal parameters in the reference-camera frame.
        free: mask of the parameters estimated in the optimisation gauge; ``gauge``: the held
            world-frame set; ``held_reason``: name -> why held.
        rms_px: reprojection RMS (2-D norm) over the inliers; ``sigma_px``: a-posteriori noise
            per coordinate; ``n_inliers``, ``n_outliers``.
        iterations: LM iterations summed over rounds; ``rounds``; ``converged``; ``seconds``.
        rank_min_singular: smallest relative singular value of the column-scaled Jacobian at
            the start (gauge check), ``rank``/``n_unknowns``.
    """

    model: MCPCModel
    model_gauge: MCPCModel
    fx: float
    mu: float
    cx: float
    cy: float
    fx_std: float
    mu_std: float
    T_left_right: np.ndarray
    T_world_cam: np.ndarray
    ref_config: int
    point_ids: np.ndarray
    X_world: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    free: np.ndarray
    gauge: GaugeChoice
    held_reason: dict[str, str]
    rms_px: float
    sigma_px: float
    n_inliers: int
    n_outliers: int
    iterations: int
    rounds: int
    converged: bool
    seconds: float
    rank_min_singular: float
    rank: int
    n_unknowns: int
    diagnostics: dict = field(default_factory=dict)


def joint_refine(
    obs: Observations,
    q: np.ndarray,
    sc,
    ident: IdentificationResult,
    used: np.ndarray,
    *,
    scale_markers: tuple[int, int],
    scale_distance_m: float,
    scale_sigma_m: float = 1e-7,
    joint_sigma: float | np.ndarray | None = None,
    pixel_sigma_px: float | None = None,
    min_pixel_sigma_px: float = 0.01,
    loss: str = "soft_l1",
    robust_scale_px: float = 1.0,
    outlier_px: float = 3.0,
    max_rounds: int = 5,
    max_iter: int = 100,
    tol: float = 1e-12,
) -> JointRefinementResult:
    """Refine kinematics, intrinsics, rig and points together from the corner observations.

    Args:
        obs: the observations the two-stage method used (configs indexed like ``q``).
        q: (m, n) joint read-backs, rad.
        sc: the :class:`calib.selfcal.SelfCalibrationResult` (metric, world = reference camera).
        ident: the two-stage :class:`calib.identify.IdentificationResult` in the same world.
        used: configuration indices the two-stage identification used (registered).
        scale_markers, scale_distance_m: the two scale markers and the distance of their centres.
        scale_sigma_m: the scale residual is ``(|c_a - c_b| - d) / scale_sigma_m`` px (hard).
        joint_sigma: standard deviation of the joint read-back errors (rad / m; scalar or (n,)),
            e.g. encoder quantisation ``1 / (counts_per_rad sqrt(12))``. When given, every
            active configuration gets joint corrections ``dq`` with the Gaussian prior
            ``sigma_px dq / joint_sigma`` (errors in variables: the maximum-likelihood estimate
            when both the corners and the read-back are noisy). None: read-back taken as exact.
        pixel_sigma_px: corner noise per coordinate that scales the joint prior; default the
            camera stage's a-posteriori value (bundle-adjustment residuals, dof-corrected),
            at least ``min_pixel_sigma_px``.
        loss: ``"soft_l1"`` (robust rounds with outlier rejection, then a plain least-squares
            pass) or ``"linear"`` (plain least squares on the two-stage inliers only).
        robust_scale_px, outlier_px: soft-L1 scale; minimum outlier threshold (the threshold is
            ``max(outlier_px, 4.5 sigma)``).

    Raises:
        JointRefinementError: the scale markers are not reconstructed, the gauge is not fixed
            (rank-deficient Jacobian) or the adjustment does not converge.
    """
    t_start = time.perf_counter()
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = len(q)
    if obs.n_configs != m:
        raise ValueError(f"obs has {obs.n_configs} configurations but q has {m} rows")
    if not sc.is_metric:
        raise JointRefinementError("the camera stage result is not metric (no scale markers)")
    used = np.asarray(used, dtype=np.int64)
    active_cfg = np.zeros(m, bool)
    active_cfg[used] = True
    model0 = ident.model
    idx = minimal_indices(model0.joint_types)
    names = tuple(param_names(idx))

    gauge = choose_gauge(model0)
    held_reason = {h: "gauge (world frame, two-stage value)" for h in gauge.held}
    for h in ident.held:
        held_reason.setdefault(h, ident.held_reason.get(h, "held by the two-stage method"))
    free = np.array([nm not in held_reason for nm in names])
    free_idx = idx[free]

    # ---- rows: observations of the used configurations whose point is reconstructed
    ids, pidx_all = obs.point_index()
    if not np.array_equal(ids, sc.point_ids):
        raise ValueError("obs and the camera-stage result disagree on the point ids")
    has_X = np.isfinite(sc.X_world).all(axis=1)
    cand = active_cfg[obs.config] & has_X[pidx_all]
    view_all = obs.view
    active = cand & np.asarray(sc.inlier, bool)
    scale_pts = []
    for mk in scale_markers:
        want = 4 * int(mk) + np.arange(4)
        pos = np.searchsorted(ids, want)
        if not (
            np.all(pos < len(ids)) and np.array_equal(ids[np.minimum(pos, len(ids) - 1)], want)
        ):
            raise JointRefinementError(f"scale marker {mk} is not observed")
        if not has_X[pos].all():
            raise JointRefinementError(
                f"scale marker {mk} is not fully reconstructed by the camera stage; it must be "
                "seen in at least two views"
            )
        scale_pts.append(pos)

    X = np.where(has_X[:, None], sc.X_world, np.nan)
    use_dq = joint_sigma is not None
    pose_model = KinematicPoses(
        model0, q, free_idx, inv_pose(sc.T_left_right), active_cfg, joint_corrections=use_dq
    )
    p = pose_model.initial_params()
    if pixel_sigma_px is None:
        inl = np.asarray(sc.inlier, bool) & np.isfinite(sc.residuals).all(axis=1)
        n_ba = 2 + 6 * (len(used) - 1) + 5 + 3 * int(has_X.sum())
        dof_ba = max(2 * int(inl.sum()) - n_ba, 1)
        pixel_sigma_px = float(np.sqrt(np.sum(sc.residuals[inl] ** 2) / dof_ba))
    pixel_sigma_px = max(float(pixel_sigma_px), float(min_pixel_sigma_px))
    if use_dq:
        js = np.broadcast_to(np.asarray(joint_sigma, dtype=float), (model0.n,))
        if not (np.all(np.isfinite(js)) and np.all(js > 0)):
            raise ValueError(f"joint_sigma must be positive and finite, got {joint_sigma}")
        prior_cols = pose_model.dq_cols
        prior_w = np.tile(pixel_sigma_px / js, len(used))
    else:
        prior_cols, prior_w = np.zeros(0, np.int64), np.zeros(0)
    fx, mu = float(sc.fx), float(sc.mu)
    w_scale = 1.0 / float(scale_sigma_m)

    def build(act):
        pts_used = np.zeros(len(ids), bool)
        nviews = np.zeros(len(ids), int)
        key = np.unique(pidx_all[act] * (2 * m) + view_all[act])
        np.add.at(nviews, key // (2 * m), 1)
        pts_used = has_X & (nviews >= 2)
        for sp_ in scale_pts:
            if not pts_used[sp_].all():
                raise JointRefinementError(
                    "a scale-marker corner lost its observations (fewer than 2 inlier views); "
                    "the scale cannot be fixed"
                )
        act = act & pts_used[pidx_all]
        remap = -np.ones(len(ids), np.int64)
        remap[pts_used] = np.arange(int(pts_used.sum()))
        prob = _Problem(
            pose_model,
            view_all[act],
            remap[pidx_all[act]],
            obs.uv[act],
            int(pts_used.sum()),
            sc.cx,
            sc.cy,
            (remap[scale_pts[0]], remap[scale_pts[1]]),
            scale_distance_m,
            w_scale,
            prior_cols,
            prior_w,
        )
        return prob, act, pts_used

    rounds = max_rounds if loss != "linear" else 0
    total_it = 0
    converged = False
    diag: dict = {}
    rank_info = None
    status, message = 0, ""
    for rnd in range(rounds + 1):
        last = rnd == rounds
        prob, act, pts_used = build(active)
        x0 = np.concatenate([[fx, mu], p, X[pts_used].ravel()])
        if rank_info is None:
            rank_info = _scaled_min_singular(prob.jac(x0))
            if rank_info[1] < prob.n:
                raise JointRefinementError(
                    f"the joint problem is rank deficient ({rank_info[1]} of {prob.n} unknowns "
                    f"determined): the held parameters {gauge.held} do not fix the gauge for "
                    "these data -- check that every joint moves and that the scale markers are "
                    "seen"
                )
        x, r, cost, it, nfev, status, message = _levenberg_marquardt(
            prob, x0, "linear" if last else loss, robust_scale_px, max_iter, tol if last else 1e-9
        )
        total_it += it
        fx, mu, p, Xu = prob.unpack(x)
        fx, mu, p = float(fx), float(mu), p.copy()
        X = np.full_like(X, np.nan)
        X[pts_used] = Xu
        if last:
            converged = status > 0
            break
        # reclassify every candidate row with the current estimate
        T = pose_model.poses(p)
        ok = cand & np.isfinite(X[pidx_all]).all(axis=1)
        e = np.full(len(obs), np.inf)
        rr, zz = reprojection_residuals(
            fx, mu, sc.cx, sc.cy, T, np.nan_to_num(X), view_all[ok], pidx_all[ok], obs.uv[ok]
        )
        e[ok] = np.where(zz > 0, np.linalg.norm(rr, axis=1), np.inf)
        n_res = 2 * int(act.sum())
        dof = max(n_res + len(prior_cols) + 1 - prob.n, 1)
        sigma = float(np.median(e[act]) / _RAYLEIGH_MEDIAN) * np.sqrt(n_res / dof)
        thr = max(outlier_px, 4.5 * sigma)
        new_active = ok & (e < thr)
        if np.array_equal(new_active, active) and rnd > 0:
            active = new_active
            rounds = rnd + 1  # classification settled: do the final plain pass next
            continue
        active = new_active
    if not converged:
        raise JointRefinementError(
            f"the joint refinement did not converge within {max_iter} iterations ({message}); "
            "check the data or raise max_iter"
        )

    # ---- statistics at the solution (final least-squares Jacobian)
    J = prob.jac(x)
    rp = r[: prob.n_pix].reshape(-1, 2)
    # 6 gauge dof are removed by the held parameters, the 7th (scale) by the hard scale row
    dof = max(len(r) - prob.n, 1)
    sigma2 = float(np.sum(rp**2) + np.sum(r[prob.n_pix + 1 :] ** 2)) / dof
    kin_cols = np.r_[0, 1, 2 + np.arange(pose_model.k)]
    C = sigma2 * _inverse_block(J, kin_cols)
    fx_std = float(np.sqrt(max(C[0, 0], 0.0)))
    mu_std = float(np.sqrt(max(C[1, 1], 0.0)))
    C_rho = C[2:, 2:]

    model_g = pose_model.kinematic_model(p)
    ref = int(sc.ref_config) if active_cfg[sc.ref_config] else int(used[0])
    q_act = pose_model.joints(p)  # read-back + estimated corrections, active configurations
    q_ref = q_act[np.searchsorted(np.flatnonzero(active_cfg), ref)][None]

    def to_ref_frame(theta: np.ndarray) -> MCPCModel:
        flat = model_g.params.reshape(-1).copy()
        flat[free_idx] = theta
        mg = model_g.with_params(flat)
        T_w_ref = fk_tool(mg, q_ref)[0]
        return express_in_frame(mg, inv_pose(T_w_ref), like=model0)

    model_ref = to_ref_frame(p[: pose_model.k])
    # covariance in the reference-camera frame: propagate through the re-expression
    Hm = np.empty((idx.size, pose_model.k))
    for j in range(pose_model.k):
        h = 1e-7
        e_ = np.zeros(pose_model.k)
        e_[j] = h
        Hm[:, j] = (
            minimal_difference(to_ref_frame(p[: pose_model.k] + e_), model_ref)
            - minimal_difference(to_ref_frame(p[: pose_model.k] - e_), model_ref)
        ) / (2 * h)
    cov_ref = Hm @ C_rho @ Hm.T
    std = np.sqrt(np.clip(np.diag(cov_ref), 0.0, None))
    for nm, why in held_reason.items():
        if not why.startswith("gauge"):
            std[names.index(nm)] = np.nan

    T_ref_world = inv_pose(fk_tool(model_g, q_ref)[0])
    X_ref = X @ T_ref_world[:3, :3].T + T_ref_world[:3, 3]
    T_rl = pose_model.rig(p)
    T_wc = np.full((m, 2, 4, 4), np.nan)
    TL = fk_tool(model_ref, q_act)
    T_wc[active_cfg, 0] = TL
    T_wc[active_cfg, 1] = TL @ inv_pose(T_rl)

    e_fin = np.linalg.norm(rp, axis=1)
    rms = float(np.sqrt(np.mean(e_fin**2)))
    diag["cost"] = cost
    diag["status"] = int(status)
    diag["message"] = message
    diag["scale_residual_m"] = float(r[prob.n_pix] / w_scale)
    diag["pixel_sigma_px"] = pixel_sigma_px
    diag["joint_sigma"] = None if not use_dq else js.tolist()
    if use_dq:
        dq = p[pose_model.dq_cols].reshape(-1, model0.n)
        diag["joint_correction_rms"] = np.sqrt(np.mean(dq**2, axis=0)).tolist()
    diag["gauge_condition_number"] = gauge.condition_number
    return JointRefinementResult(
        model=model_ref,
        model_gauge=model_g,
        fx=fx,
        mu=mu,
        cx=float(sc.cx),
        cy=float(sc.cy),
        fx_std=fx_std,
        mu_std=mu_std,
        T_left_right=inv_pose(T_rl),
        T_world_cam=T_wc,
        ref_config=ref,
        point_ids=ids,
        X_world=X_ref,
        names=names,
        values=model_ref.params.reshape(-1)[idx],
        std=std,
        covariance=cov_ref,
        free=free,
        gauge=gauge,
        held_reason=held_reason,
        rms_px=rms,
        sigma_px=float(np.sqrt(sigma2)),
        n_inliers=int(act.sum()),
        n_outliers=int((cand & ~act).sum()),
        iterations=total_it,
        rounds=rnd + 1,
        converged=converged,
        seconds=time.perf_counter() - t_start,
        rank_min_singular=rank_info[0],
        rank=rank_info[1],
        n_unknowns=prob.n,
        diagnostics=diag,
    )


def tool_point_covariance(
    res: JointRefinementResult, q: np.ndarray, T_cam_point: np.ndarray
) -> np.ndarray:
    """Covariance (k, 3, 3) m^2 of a point rigidly attached to the camera (e.g. the tool tip,
    ``T_cam_point`` (4, 4)) at joints ``q`` (k, n), from the parameter covariance (first order,
    reference-camera frame). The Cramer-Rao bound of the predicted tool tip when the noise model
    is right."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(res.model.joint_types)
    T = fk_tool(res.model, q)
    Jb = identification_jacobian(res.model, q)[:, :, idx]  # body twist of the camera
    pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
    # point in world: T p; d = R (dv + dw x p) = R (dv - p x dw)
    Jp = T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])  # (k, 3, P)
    cov = np.nan_to_num(res.covariance)
    return Jp @ cov @ np.swapaxes(Jp, -1, -2)


# --------------------------------------------------------------------------------------------
# calibration.json integration (used by calib.calibrate.calibrate(method="joint"))
# --------------------------------------------------------------------------------------------


def encoder_sigma(robot) -> np.ndarray | None:
    """Standard deviation (n,) rad / m of a read-back rounded to the nearest encoder count,
    ``1 / (counts_per_unit sqrt(12))``; None if the robot has no finite encoder resolution."""
    cpu = np.asarray(getattr(robot, "counts_per_unit", np.full(robot.n, np.inf)), dtype=float)
    if not np.all(np.isfinite(cpu) & (cpu > 0)):
        return None
    return 1.0 / (cpu * np.sqrt(12.0))


def method_summary(doc: dict) -> dict:
    """The method-specific part of a calibration document (for ``document["methods"]``)."""
    keys = ("intrinsics", "rig", "reprojection_rms_px", "observations", "hand_eye", "parameters")
    out = {k: doc[k] for k in keys if k in doc}
    out["mcpc_params_si"] = doc["mcpc"]["params_si"]
    return out


def _round(T: np.ndarray, digits: int = 9) -> list:
    return np.round(np.asarray(T, dtype=float), digits).tolist()


def joint_document(doc: dict, res: JointRefinementResult, robot) -> dict:
    """A copy of the two-stage calibration document with the joint result as the final one.

    Replaced: intrinsics, rig, reprojection RMS, observations, hand-eye, parameters (estimate,
    std in the reference-camera frame), mcpc, dh, camera poses. Added: ``joint`` (gauge, rank,
    iterations, time, noise levels). ``identification`` still describes the two-stage start.
    """
    import copy
    import warnings

    from calib.identify import to_dh
    from calib.mcpc import dh_to_mcpc, shape_matrices
    from calib.transforms import rot_z

    out = copy.deepcopy(doc)
    model = res.model
    out["intrinsics"].update(
        {
            "fx": res.fx,
            "fy": res.fx * res.mu,
            "mu": res.mu,
            "fx_std": res.fx_std,
            "mu_std": res.mu_std,
        }
    )
    out["rig"] = {"T_left_right_m": _round(res.T_left_right)}
    out["reprojection_rms_px"] = res.rms_px
    out["observations"] = {"inliers": res.n_inliers, "outliers": res.n_outliers}
    idx = minimal_indices(model.joint_types)
    ang = param_is_angle(idx)
    params = []
    for j, (name, k, a) in enumerate(zip(res.names, idx, ang)):
        s = 180.0 / np.pi if a else 1000.0
        params.append(
            {
                "name": name,
                "unit": "deg" if a else "mm",
                "estimate": float(model.params.reshape(-1)[k] * s),
                "std": float(res.std[j] * s) if np.isfinite(res.std[j]) else None,
                "held": name in res.held_reason and not res.held_reason[name].startswith("gauge"),
            }
        )
    out["parameters"] = params

    def last_link_to_tool(mdl: MCPCModel) -> np.ndarray:
        return rot_z(mdl.joint_offsets[-1]) @ shape_matrices(mdl.params[-1])

    T_flange_cam = inv_pose(last_link_to_tool(dh_to_mcpc(robot))) @ last_link_to_tool(model)
    out["hand_eye"] = {"T_flange_cam_m": _round(T_flange_cam)}
    out["mcpc"].update(
        {"joint_offsets_rad": model.joint_offsets.tolist(), "params_si": model.params.tolist()}
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dh = to_dh(model, robot)
    if dh is None:
        out["dh"] = None
        out["dh_note"] = "; ".join(str(w.message) for w in caught) or "not representable"
    else:
        out["dh"] = {
            "rows": [
                {
                    "theta_offset_deg": np.degrees(o),
                    "d_mm": d * 1000,
                    "a_mm": a_ * 1000,
                    "alpha_deg": np.degrees(al),
                }
                for o, d, a_, al in dh.rows()
            ]
        }
        out["dh_note"] = None
    frames = np.asarray(out["camera_poses"]["frame_index"])
    used = res.diagnostics.get("used_configs")
    if used is not None and len(used) == len(frames):
        out["camera_poses"]["T_world_cam_left_m"] = [_round(T) for T in res.T_world_cam[used, 0]]
    out["joint"] = {
        "gauge_held": list(res.gauge.held),
        "gauge_method": res.gauge.method,
        "gauge_condition_number": res.gauge.condition_number,
        "held": {n: r for n, r in res.held_reason.items()},
        "rank": res.rank,
        "n_unknowns": res.n_unknowns,
        "rank_min_singular_scaled": res.rank_min_singular,
        "iterations": res.iterations,
        "rounds": res.rounds,
        "converged": res.converged,
        "sigma_px": res.sigma_px,
        "pixel_sigma_prior_px": res.diagnostics.get("pixel_sigma_px"),
        "joint_sigma": res.diagnostics.get("joint_sigma"),
        "joint_correction_rms": res.diagnostics.get("joint_correction_rms"),
        "scale_residual_m": res.diagnostics.get("scale_residual_m"),
        "note": (
            "one-step maximum-likelihood refinement (calib.joint_refine) started from the "
            "two-stage result; parameters and std are in the reference-camera frame like the "
            "two-stage ones; 'identification' describes the two-stage start"
        ),
    }
    return out


def refine_calibration(out, obs: Observations, q: np.ndarray, robot, ds_info, **kw):
    """Run :func:`joint_refine` on a two-stage :class:`calib.calibrate.CalibrationOutput` and
    return a new one whose document and model are the joint result (``joint`` set), with both
    methods summarised in ``document["methods"]``. ``ds_info``: the dataset's info (scale
    markers and distance). Keyword arguments go to :func:`joint_refine`; by default the joint
    read-back is modelled with the robot's encoder resolution (:func:`encoder_sigma`)."""
    import dataclasses

    sc, ident = out.selfcal, out.identification
    used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
    kw.setdefault("joint_sigma", encoder_sigma(robot))
    res = joint_refine(
        obs,
        q,
        sc,
        ident,
        used,
        scale_markers=tuple(ds_info.scale_ids),
        scale_distance_m=ds_info.scale_length_m,
        **kw,
    )
    res.diagnostics["used_configs"] = used
    doc = joint_document(out.document, res, robot)
    doc["method"] = "joint"
    doc["methods"] = {"two-stage": method_summary(out.document), "joint": method_summary(doc)}
    return dataclasses.replace(out, document=doc, model=res.model, joint=res)


def aligned_tool_rms_bound(
    res: JointRefinementResult, q: np.ndarray, T_cam_point: np.ndarray
) -> float:
    """Predicted RMS (m) of a camera-attached point's error over postures ``q`` (k, n) *after*
    the best rigid alignment (the validation metric of :mod:`calib.report`), from the parameter
    covariance (first order): ``sqrt(trace(P S P) / k)`` with ``S`` the (3k, 3k) covariance of
    the stacked points (:func:`tool_point_covariance` with cross terms) and ``P`` the projector
    removing rigid motions. With the a-posteriori noise level this is the Cramer-Rao bound of
    the metric for an unbiased estimator."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    idx = minimal_indices(res.model.joint_types)
    T = fk_tool(res.model, q)
    Jb = identification_jacobian(res.model, q)[:, :, idx]
    pt = np.asarray(T_cam_point, dtype=float)[:3, 3]
    Jp = (T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])).reshape(-1, idx.size)
    S = Jp @ np.nan_to_num(res.covariance) @ Jp.T
    P_world = (T @ np.asarray(T_cam_point, dtype=float))[:, :3, 3]
    c = P_world - P_world.mean(axis=0)
    rigid = np.concatenate(
        [np.tile(np.eye(3), (len(q), 1)), -skew(c).reshape(-1, 3)], axis=1
    )  # (3k, 6): translation, rotation about the centroid
    Q, _ = np.linalg.qr(rigid)
    P = np.eye(len(S)) - Q @ Q.T
    return float(np.sqrt(max(np.trace(P @ S @ P), 0.0) / len(q)))
