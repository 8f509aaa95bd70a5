"""New views at the calibration's own postures, each against its frame there (issue #29).

A cell that checks its calibration every morning drives the same few postures every day, often
the calibration's own. A new view at a posture where the calibration has a frame carries the
same per-configuration misfit as that frame (what no rigid chain expresses: a joint's
compliance, the per-view pose misfit of the real sets, docs/real-data.md), and the check's
covariance for a new view (:mod:`selfcal.calibration.drift.images`) counts that misfit as new,
independent of the calibration's estimate, while at the calibration's posture the fit has
already absorbed part of it. So such a view is tested by the difference of its residuals from
its frame's on the board points both detect,

    d = (uv_new - f(q_new)) - (uv_cal - f(q_cal))

(``f`` the calibration's prediction from the joint readings): the calibration's estimation
error cancels (both residuals hold the same ``H (theta_hat - theta)``: no ``H C H^T`` term),
the misfit that depends on the posture alone cancels, and what is left is both views' corner
noise (the file's white noise, or the bounds' when no per-view misfit was counted) and joint
read-back noise: ``Sigma_d = Sigma_new + Sigma_cal`` with no model error. A change since the
calibration moves ``uv_new`` alone, by the same columns as an unpaired view's.

Only where the calibration's own frames showed a per-view misfit beyond the corner noise
(``accuracy.view_jitter`` counted: :attr:`selfcal.calibration.drift.images.ViewNoise.misfit_counted`):
without it the new view alone is the stronger test, its noise counted once rather than twice (a
0.2 mm mount shift at 0.2 px found in 86 % of the simulated checks at the calibration's postures
alone, 55 % paired: ``python -m selfcal.benchmarks.drift_morning``).

What this assumes: the misfit at a posture repeats when the arm returns to it (the readings
within :data:`POSTURE_TOL`). A misfit that differs between exposures at one posture (a board
that moved, a warm-up) is not counted and reads as a change; the real sets have no repeated
posture to measure it on (docs/real-data.md). Neglected: the correlation of ``d`` with the
other, unpaired, views' residuals through the frame's own noise in the calibration's estimate
(of the order of one frame's leverage in the fit, about 1 / frames).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from selfcal.calibration.drift.views import ViewJacobians, view_jacobians
from selfcal.camera import CameraModel
from selfcal.kinematics.tool_error import ToolErrorModel

__all__ = ["MIN_SHARED", "POSTURE_TOL", "pair_views", "same_posture"]

POSTURE_TOL = 1e-4
"""rad / m: joint readings this close (every joint) are the same posture (a taught posture
driven again reads within a few encoder counts: 0.0007 deg, 1.2e-5 rad, per count on a UR5e)."""
MIN_SHARED = 4
"""Board points a new view and its frame must both detect to be compared (fewer: the view is
tested as a new one)."""


def same_posture(q_new: np.ndarray, q_frames: np.ndarray, tol: float = POSTURE_TOL) -> np.ndarray:
    """(m,) per joint vector of ``q_new`` (m, n) the index into ``q_frames`` (c, n) (rad / m)
    of the frame at the same posture (every joint within ``tol``; the nearest of several), or
    -1 when none is."""
    if len(q_frames) == 0:
        return np.full(len(q_new), -1)
    gap = np.max(np.abs(q_new[:, None, :] - q_frames[None, :, :]), axis=2)
    best = np.argmin(gap, axis=1)
    return np.where(gap[np.arange(len(q_new)), best] <= tol, best, -1)


def _shared(Xa: np.ndarray, Xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the board points ``Xa`` and ``Xb`` (k, 3) that are the same points."""
    at = {x.tobytes(): j for j, x in enumerate(np.asarray(Xb, float))}
    pairs = [(i, at[x.tobytes()]) for i, x in enumerate(np.asarray(Xa, float)) if x.tobytes() in at]
    ia, ib = (np.array(p, int) for p in zip(*pairs, strict=True)) if pairs else ([], [])
    return np.asarray(ia, int), np.asarray(ib, int)


def pair_views(views: list[ViewJacobians], new: list[tuple[int, np.ndarray, np.ndarray]],
               q: np.ndarray, frames: list[tuple[int, np.ndarray, np.ndarray]],
               q_frames: np.ndarray, *, em: ToolErrorModel, camera: CameraModel,
               eye_to_hand: bool, pixel_sigma_px: float,
               joint_sigma_rad: np.ndarray | None) -> list[ViewJacobians]:  # fmt: skip
    """``views`` (:func:`selfcal.calibration.drift.views.view_jacobians` of the new views
    ``new``: frame ``f`` into ``q`` (m, n) rad / m, board points ``X`` (k, 3) m, detected
    ``uv`` (k, 2) px) with each one at the posture of a calibration frame (``frames``, the
    calibration's dataset's views of the same camera in the same form, ``f`` into
    ``q_frames``) that shares at least :data:`MIN_SHARED` board points replaced by its paired
    difference from that frame (module docstring; ``paired`` set), linearised at the
    calibration ``em``, ``camera`` with the white corner noise ``pixel_sigma_px`` (px) and the
    joint read-back ``joint_sigma_rad`` (n,) or None of each view; the others as they are."""
    if not frames:
        return list(views)
    at = same_posture(
        np.array([q[f] for f, _, _ in new]), np.asarray(q_frames)[[f for f, _, _ in frames]]
    )
    quiet = dataclasses.replace(em, model_error_m=0.0, model_error_rad=0.0)  # it repeats: cancels
    out = []
    for v, (f, X, uv), i in zip(views, new, at, strict=True):
        ia, ib = _shared(X, frames[i][1]) if i >= 0 else ((), ())
        if len(ia) < MIN_SHARED:
            out.append(v)
            continue
        fc, Xc, uvc = frames[i]
        a, b = (view_jacobians(quiet, camera, qv, Xv, uvv, eye_to_hand=eye_to_hand,
                               pixel_sigma_px=pixel_sigma_px, joint_sigma_rad=joint_sigma_rad)
                for qv, Xv, uvv in ((q[f], X[ia], uv[ia]), (q_frames[fc], Xc[ib], uvc[ib])))  # fmt: skip
        out.append(dataclasses.replace(a, r=a.r - b.r, local=a.local + b.local, paired=True))
    return out
