"""The per-view misfit of a board calibration, as a jitter of the chain's tool pose or per pose
direction (issue #29).

A calibration whose model misfits leaves residuals in its own frames (its first camera's pixels
predicted from the joints alone by the stored model) that do not look like corner noise: on
the real Nachi sets (tests/real) 94 % of their energy lies in the span of each frame's 6 pose
columns (``A``, the pixels' derivative by a body twist of the chain's tool: the camera,
eye-to-hand the board), where white corner noise would put 6 of every ``2k`` (3 %), and the
rest is 0.10 px RMS against the 0.43 px corner noise the bounds take from the fit's RMS
(photoneo, ``selfcal calibrate`` on groups 1-5 as the real tier runs it: the block's
``pose_share`` and ``rest_rms_px``; docs/real-data.md). Such a
misfit moves each new view as a small pose error of its own: the drift check
(:mod:`selfcal.calibration.drift.views`) must carry it per view, in that form, or every
directed test of a change rejects an unchanged arm.

Per frame ``i``: ``xi_i = argmin |r_i - A_i xi|`` (m, rad) and
``N_i = s^2 (A_i^T A_i)^-1 + tw_i S_j tw_i^T`` what the corner noise ``s`` (the bounds') and the
joint read-back noise (``S_j``, ``tw_i`` the joints' body twists) give it. The jitter is
counted when ``sum_i xi_i^T N_i^-1 xi_i`` exceeds its ``6 m`` by more than
:data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` standard errors (``sqrt(12 m)``): its
covariance (6, 6) is then the mean of ``xi_i xi_i^T - N_i`` (negative eigenvalues set to 0),
else 0. A calibration that fits (the simulated ones, nearly all) has none: the fit absorbs part of each
frame's pose span, so its statistic lies below ``6 m``.

Counted, the jitter holds the misfit's energy in the pose spans, so the corner noise beside it
is not the bounds' (from the fit's RMS, which holds that energy too: it was counted twice, the
check's prediction 1.43 px RMS against the 0.81 px measured on photoneo's held-out group) but
what lies outside them, in two parts per frame (``U_i`` an orthonormal basis of the camera's
free parameters' pixel columns with the frame's pose span projected out, :func:`camera_directions`):

- the white corner noise ``w`` (:attr:`ViewJitter.white_px`): the residuals outside both the
  pose span and ``U_i``, over their ``sum (2k_i - 6 - rank U_i)`` degrees of freedom;
- a per-view misfit in the camera's directions ``c`` (:attr:`ViewJitter.camera_misfit_px`, px
  per direction): what the residuals leave in ``U_i`` beyond ``w``, over ``sum rank U_i - p_c``
  degrees of freedom (the calibration's camera fitted its ``p_c`` free parameters to those
  directions). New views show it where the calibration's own frames hide it: with ``w`` alone
  (0.08 px on both Nachi sets)
  the check's test of a camera change rejects the unchanged arm's held-out group (photoneo
  p = 1e-5 before Bonferroni), with it not.

The jitter is then the mean of ``xi_i xi_i^T - N_i`` with ``w`` in ``N_i``. That mean is right
for a rigid pose error of each view, but a misfit of the pixels that merely lies in the pose
span (a lens's, a board's) gives each frame a pose error ``xi_i`` that is large along what that
frame measures poorly and costs it few pixels; carried to new views that measure it well, the
mean predicts far more than they show (mecheye: 2.75 px^2 per corner on its own frames against
their 0.75 in the pose span; a frame's ``xi_i`` alone carried to the others gives them 22 px^2).
So a second form is weighed against it: a per-view misfit ``g`` in each of the 6 orthonormal
directions of a view's pose span (in pixels, :attr:`ViewJitter.pose_misfit_px`), ``g^2`` the
frames' pose-span energy beyond ``w`` and the joints' read-back over their ``6 m`` directions.
Each frame's ``xi_i`` is predicted from the other frames by each form (``J`` the others' mean,
and ``g^2 (A_i^T A_i)^-1``, each plus ``N_i``) and the form with the larger Gaussian
log-likelihood summed over the frames is kept (:func:`_per_direction`): ``g`` on mecheye, the
jitter on photoneo and on a simulated rigid jitter (tests/unit/test_view_jitter.py).

The drift check adds ``A_i J A_i^T`` (or ``g^2 P_i``, ``P_i`` the projection on the view's pose
span) ``+ c^2 U_i U_i^T + w^2 I`` to every new view in place of the bounds' ``s^2 I``
(:func:`selfcal.calibration.drift.images.calibration_views`); a calibration whose jitter is not
counted keeps the bounds' noise and nothing else. Nothing here reads truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.misfit import board_view
from selfcal.camera import CameraModel
from selfcal.errors import InputError
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel

__all__ = [
    "KEY",
    "ViewJitter",
    "camera_directions",
    "psd_part",
    "view_jitter",
    "view_jitter_from_json",
]

KEY = "view_jitter"
"""The ``accuracy`` block's key of :meth:`ViewJitter.to_json`."""


@dataclass(frozen=True)
class ViewJitter:
    """The per-view pose misfit of a calibration's own frames (module docstring).

    Attributes:
        covariance: (6, 6) of a body twist ``[v; w]`` (m, rad) of the chain's tool per view
            (zeros when not counted); statistic: ``sum xi^T N^-1 xi`` over ``views`` frames
            (expected ``6 views`` without a misfit); counted: it exceeded that (module
            docstring); pose_share: the share of the residuals' sum of squares in the frames'
            pose spans; rest_rms_px: the RMS of the rest (px, per coordinate over its degrees
            of freedom); white_px: the white corner noise outside the pose spans and the camera's
            directions, camera_misfit_px: the per-view misfit per camera direction (module
            docstring; px; None in a file written before them: the check keeps the bounds'
            noise then); pose_misfit_px: the per-view misfit per pose direction (px) when its
            frames' likelihood prefers it to the jitter (module docstring), else None (and in
            a file written before it): the check carries the jitter then.
    """

    covariance: np.ndarray
    statistic: float
    views: int
    counted: bool
    pose_share: float
    rest_rms_px: float
    white_px: float | None = None
    camera_misfit_px: float | None = None
    pose_misfit_px: float | None = None

    def to_json(self) -> dict:
        """The block (SI; px)."""
        return {
            "white_px": self.white_px,
            "camera_misfit_px": self.camera_misfit_px,
            "pose_misfit_px": self.pose_misfit_px,
            "covariance_si": self.covariance.tolist(),
            "statistic": self.statistic,
            "views": self.views,
            "counted": self.counted,
            "pose_share": self.pose_share,
            "rest_rms_px": self.rest_rms_px,
            "what": "per-view jitter of the chain's tool pose (body twist, m and rad) that the "
            "calibration's own frames show beyond the corner noise; the drift check adds it to "
            "every new view (or, where pose_misfit_px is given, that misfit in each of the "
            "view's 6 pose directions instead), with camera_misfit_px per camera direction and "
            "white_px in place of the bounds' corner noise",
        }


def camera_directions(A: np.ndarray, Jc: np.ndarray) -> np.ndarray:
    """(2k, r) an orthonormal basis of a view's camera columns ``Jc`` (2k, c) (px per camera
    parameter) with the span of its pose columns ``A`` (2k, 6) projected out (r <= c, the
    columns the pose cannot mimic)."""
    Q = Jc - A @ np.linalg.lstsq(A, Jc, rcond=None)[0]
    U, S, _ = np.linalg.svd(Q, full_matrices=False)
    return U[:, S > 1e-9 * S[0]] if S.size and S[0] > 0 else U[:, :0]


def view_jitter(model: MCPCModel, camera: CameraModel, q: np.ndarray,
                frames: list[tuple[int, np.ndarray, np.ndarray]], *, eye_to_hand: bool,
                pixel_sigma_px: float,
                joint_sigma: float | np.ndarray | None) -> ViewJitter | None:  # fmt: skip
    """The per-view misfit (module docstring) of the calibrated ``model`` with its first
    ``camera`` in its own ``frames``: each a frame index into the joints ``q`` (m, n) rad / m,
    its board points (k, 3) m (board frame) and detected pixels (k, 2); ``pixel_sigma_px`` the
    corner noise (the bounds'); ``joint_sigma`` the read-back noise (rad / m, scalar or (n,)) or None (exact).
    None with fewer than 2 frames of 4 corners or more: nothing to estimate it from (the one
    place of that rule).
    """
    frames = [fr for fr in frames if len(fr[1]) >= 4]
    if len(frames) < 2:
        return None
    q_frames = np.asarray(q, float)[[f for f, _, _ in frames]]
    T, tw = fk_tool(model, q_frames), joint_twists(model, q_frames)
    xis, infos, rest, dof, total, in_cam, cam_dof = [], [], 0.0, 0, 0.0, 0.0, 0
    js2 = 0.0 if joint_sigma is None else np.broadcast_to(np.asarray(joint_sigma, float) ** 2,
                                                          (tw.shape[2],))  # fmt: skip
    in_pose, joints_px2 = [], []  # per frame: the pose span's energy, the joints' there (px^2)
    for (_, X, uv), Ti, twi in zip(frames, T, tw, strict=True):
        _, uv_hat, A, Jc = board_view(camera, Ti, X, eye_to_hand)
        r = (np.asarray(uv, float) - uv_hat).reshape(-1)
        xi, *_ = np.linalg.lstsq(A, r, rcond=None)
        e = r - A @ xi
        U = camera_directions(A, Jc.reshape(len(r), -1))
        rest += float(e @ e)
        in_cam += float(np.sum((U.T @ e) ** 2))
        total += float(r @ r)
        dof += len(r) - 6
        cam_dof += U.shape[1]
        xis.append(xi)
        infos.append(A.T @ A)
        in_pose.append(float(r @ r - e @ e))
        joints_px2.append(float(np.sum((A @ twi) ** 2 * js2)))
    # the white corner noise and the camera directions' misfit beyond it (module docstring)
    white2 = (rest - in_cam) / max(dof - cam_dof, 1)
    cam2 = max(in_cam / max(cam_dof - len(camera.free), 1) - white2, 0.0)
    s2 = pixel_sigma_px**2
    n = len(frames)
    N = [s2 * np.linalg.inv(info) + (tw[i] * js2) @ tw[i].T for i, info in enumerate(infos)]
    stat = float(sum(x @ np.linalg.solve(Ni, x) for x, Ni in zip(xis, N, strict=True)))
    share = 1.0 - rest / total if total > 0 else 0.0
    rest_rms = float(np.sqrt(rest / dof))
    white, cam = float(np.sqrt(white2)), float(np.sqrt(cam2))
    if stat <= 6 * n + Z_MODEL_ERROR * np.sqrt(12 * n):
        return ViewJitter(np.zeros((6, 6)), stat, n, False, share, rest_rms, white, cam)
    # counted: the corner noise in N_i is the white one (module docstring)
    N = [Ni + (white2 - s2) * np.linalg.inv(info) for Ni, info in zip(N, infos, strict=True)]
    S = [np.outer(x, x) - Ni for x, Ni in zip(xis, N, strict=True)]
    # the pose span's energy per frame beyond the white noise and the joints' read-back
    excess = np.array(in_pose) - 6 * white2 - np.array(joints_px2)
    pose = _per_direction(xis, infos, N, S, excess)
    return ViewJitter(
        psd_part(np.mean(S, axis=0)), stat, n, True, share, rest_rms, white, cam, pose
    )


def psd_part(M: np.ndarray) -> np.ndarray:
    """The symmetric part of ``M`` with its negative eigenvalues set to 0 (the jitter's
    covariance from the mean of ``xi_i xi_i^T - N_i``, module docstring)."""
    w, V = np.linalg.eigh((M + M.T) / 2)
    return (V * np.clip(w, 0.0, None)) @ V.T


def _log_likelihood(x: np.ndarray, cov: np.ndarray) -> float:
    """The Gaussian log-density of ``x`` under the covariance ``cov``, less its constant."""
    _, logdet = np.linalg.slogdet(cov)
    return -0.5 * (float(x @ np.linalg.solve(cov, x)) + logdet)


def _per_direction(xis: list[np.ndarray], infos: list[np.ndarray], N: list[np.ndarray],
                   S: list[np.ndarray], excess: np.ndarray) -> float | None:  # fmt: skip
    """The misfit per pose direction ``g`` (px) when it predicts each frame's pose error ``xi_i``
    (from the others) better than the jitter's mean does, else None (module docstring): per
    frame ``i`` left out, ``J`` the mean of the others' ``S_j = xi_j xi_j^T - N_j`` and ``g^2``
    their pose-span energy ``excess`` over their ``6`` directions, each frame's Gaussian
    log-likelihood under ``J + N_i`` and under ``g^2 (A_i^T A_i)^-1 + N_i`` summed."""
    n = len(xis)
    tot_S, tot_e = np.sum(S, axis=0), float(np.sum(excess))
    jitter = per_direction = 0.0
    for x, info, Ni, Si, ei in zip(xis, infos, N, S, excess, strict=True):
        g2 = max((tot_e - ei) / (6 * (n - 1)), 0.0)
        jitter += _log_likelihood(x, psd_part((tot_S - Si) / (n - 1)) + Ni)
        per_direction += _log_likelihood(x, g2 * np.linalg.inv(info) + Ni)
    if per_direction <= jitter:
        return None
    return float(np.sqrt(max(tot_e / (6 * n), 0.0)))


def view_jitter_from_json(block: dict | None, where: str) -> ViewJitter | None:
    """The ``accuracy`` block's :data:`KEY` entry, None when absent (a file written before it).

    Raises:
        InputError: the entry is malformed (named, with the fix).
    """
    doc = (block or {}).get(KEY)
    if doc is None:
        return None
    try:
        C = np.asarray(doc["covariance_si"], float)
        extra = [None if doc.get(k) is None else float(doc[k])
                 for k in ("white_px", "camera_misfit_px", "pose_misfit_px")]  # fmt: skip
        out = ViewJitter(C, float(doc["statistic"]), int(doc["views"]), bool(doc["counted"]),
                         float(doc["pose_share"]), float(doc["rest_rms_px"]), *extra)  # fmt: skip
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{where}: accuracy.{KEY} is malformed ({exc})",
                         fix="re-run `selfcal calibrate` to write it again") from exc  # fmt: skip
    if C.shape != (6, 6) or not np.all(np.isfinite(C)):
        raise InputError(f"{where}: accuracy.{KEY}.covariance_si must be a finite 6 x 6 matrix",
                         fix="re-run `selfcal calibrate` to write it again")  # fmt: skip
    return out
