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
alone, 55 % paired: ``python -m selfcal.benchmarks.drift.morning``).

Every new view at a frame's posture is paired with it; two differences from one frame share
its noise on the points both compare (``Cov(d1, d2) = Sigma_cal`` there), which the check's
covariance holds as the off-diagonal blocks of those views
(:func:`selfcal.calibration.drift.covariance.view_covariance`; before, each frame was paired with one
new view and the further ones tested as new).

What this assumes: the misfit at a posture repeats when the arm returns to it (the readings
within a few encoder counts, :func:`posture_tol`). A misfit that differs between exposures at one posture (a board
that moved, a warm-up) is not counted and reads as a change; the real sets have no repeated
posture to measure it on (docs/real-data.md).

The frame's noise moved the calibration's estimate, which every unpaired new view's residual
holds (``r_u = e_u - H_u (theta_hat - theta)``): ``Cov(d, r_u) = Cov(e_cal, theta_hat) H_u^T =
H_b C_e H_u^T`` (``H_b`` the frame's columns on the compared rows, ``C_e`` the estimate's
covariance from the frames' noise alone, the ``accuracy`` block's ``noise_covariance_si``: the
held parameters' deviation and the model error cancel in ``d`` and do not correlate with the
frame's noise; first order in ``H_new - H_b``, the same posture; the calibration's weights
taken as its frames' noise). The check's covariance holds it (review finding 6: left out before,
the paired and unpaired views' whitened residuals spread 0.32-1.78 about 1 along the frame's
columns in ``tests/unit/test_drift_null.py``'s scene, 0.80-1.21 with it); a file written before
the block gave ``noise_covariance_si`` leaves it out (:func:`noise_covariance`).
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Protocol

import numpy as np
from scipy.stats import ncx2

from selfcal.calibration.board.accuracy import board_postures_from_json
from selfcal.calibration.board.evaluate import HeldOutViews
from selfcal.calibration.drift.own import JOINT_TOL, calibration_dataset
from selfcal.calibration.drift.views import (
    ViewJacobians,
    span_basis,
    view_jacobians,
    view_white_px,
    white_level,
)
from selfcal.camera import CameraModel
from selfcal.errors import InputError, SelfCalWarning
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.kinematics.tool_error import ToolErrorModel

__all__ = [
    "MIN_SHARED",
    "Noise",
    "POSTURE_COUNTS",
    "POSTURE_TOL",
    "pair_views",
    "paired_views",
    "noise_covariance",
    "posture_tol",
    "same_posture",
]

POSTURE_TOL = 1e-4
"""rad / m: the least tolerance of :func:`posture_tol` (joint readings this close, every joint,
are the same posture where the read-back's noise is not known or finer: 1.2e-5 rad per count
on a UR5e)."""
POSTURE_COUNTS = 4.0
"""Encoder counts of each joint within which a posture driven again is the same posture: one
count is ``sqrt 12`` times the read-back's standard deviation of a joint read by its own motor
(:attr:`selfcal.robot.encoder.EncoderSpec.read_back_sigma`), 1.23e-4 .. 3.13e-4 rad on the
ER-4u (models/scorbot_er4u/er4u-paper.toml); on a differential wrist that is 0.71 of a motor
count, so the tolerance there is 2.8 of its counts."""
Px = tuple[float, float] | None
"""A view's white corner noise beside the calibration's (px), or None."""
MIN_SHARED = 4
"""Board points a new view and its frame must both detect to be compared (fewer: the view is
tested as a new one)."""


class Noise(Protocol):
    """What the pairing needs of the check's noise
    (:class:`selfcal.calibration.drift.images.ViewNoise`)."""

    @property
    def pixel_sigma_px(self) -> float: ...
    @property
    def joint_sigma_rad(self) -> np.ndarray | None: ...
    @property
    def misfit_counted(self) -> bool: ...


def posture_tol(joint_sigma: np.ndarray | None, n: int) -> np.ndarray:
    """(n,) rad / m per joint: readings this close are the same posture, :data:`POSTURE_COUNTS`
    counts of the read-back whose standard deviation ``joint_sigma`` (n,) is (the calibration's
    ``bounds.joint_sigma_deg`` in rad: the encoder's quantisation, ``count / sqrt 12``), at
    least :data:`POSTURE_TOL`; :data:`POSTURE_TOL` where it is None."""
    if joint_sigma is None:
        return np.full(n, POSTURE_TOL)
    return np.maximum(POSTURE_COUNTS * np.sqrt(12.0) * np.asarray(joint_sigma, float), POSTURE_TOL)


def same_posture(q_new: np.ndarray, q_frames: np.ndarray,
                 tol: float | np.ndarray = POSTURE_TOL) -> np.ndarray:  # fmt: skip
    """(m,) per joint vector of ``q_new`` (m, n) the index into ``q_frames`` (c, n) (rad / m)
    of the frame at the same posture (every joint within ``tol``, a number or (n,) per joint;
    the nearest of several in units of it), or -1 when none is."""
    if len(q_frames) == 0:
        return np.full(len(q_new), -1)
    gap = np.max(np.abs(q_new[:, None, :] - q_frames[None, :, :]) / tol, axis=2)
    best = np.argmin(gap, axis=1)
    return np.where(gap[np.arange(len(q_new)), best] <= 1.0, best, -1)


def _shared(Xa: np.ndarray, Xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the board points ``Xa`` and ``Xb`` (k, 3) that are the same points."""
    at = {x.tobytes(): j for j, x in enumerate(np.asarray(Xb, float))}
    pairs = [(i, at[x.tobytes()]) for i, x in enumerate(np.asarray(Xa, float)) if x.tobytes() in at]
    ia, ib = (np.array(p, int) for p in zip(*pairs, strict=True)) if pairs else ([], [])
    return np.asarray(ia, int), np.asarray(ib, int)


def pair_views(views: list[ViewJacobians], new: list[tuple[int, np.ndarray, np.ndarray]],
               q: np.ndarray, frames: list[tuple[int, np.ndarray, np.ndarray]],
               q_frames: np.ndarray, *, em: ToolErrorModel, camera: CameraModel,
               eye_to_hand: bool, pixel_sigma_px: float, joint_sigma_rad: np.ndarray | None,
               tol: float | np.ndarray = POSTURE_TOL) -> list[ViewJacobians]:  # fmt: skip
    """``views`` (:func:`selfcal.calibration.drift.views.view_jacobians` of the new views
    ``new``: frame ``f`` into ``q`` (m, n) rad / m, board points ``X`` (k, 3) m, detected
    ``uv`` (k, 2) px) with the first one at the posture (within ``tol``, :func:`same_posture`)
    of a calibration frame (``frames``, the calibration's dataset's views of the same camera in
    the same form, ``f`` into ``q_frames``) that shares at least :data:`MIN_SHARED` board
    points replaced by its paired difference from that frame (module docstring; ``paired``
    set), linearised at the calibration ``em``, ``camera`` with the white corner noise
    ``pixel_sigma_px`` (px; a new image's own where its difference shows more, as an unpaired
    view's, or its frame named where that is the noisy one: :func:`_own_noise`) and the joint read-back ``joint_sigma_rad`` (n,) or None of
    each view; the others as they are (a further view at a frame's posture too:
    :func:`_pair`)."""
    return _pair(views, new, q, frames, q_frames, em=em, camera=camera,
                 eye_to_hand=eye_to_hand, pixel_sigma_px=pixel_sigma_px,
                 joint_sigma_rad=joint_sigma_rad, tol=tol)[0]  # fmt: skip


def _pair(views: list[ViewJacobians], new: list[tuple[int, np.ndarray, np.ndarray]],
          q: np.ndarray, frames: list[tuple[int, np.ndarray, np.ndarray]], q_frames: np.ndarray,
          *, em: ToolErrorModel, camera: CameraModel, eye_to_hand: bool, pixel_sigma_px: float,
          joint_sigma_rad: np.ndarray | None,
          tol: float | np.ndarray) -> tuple[list[ViewJacobians], int]:  # fmt: skip
    """:func:`pair_views` and how many further new views at a paired frame's posture it tested
    as new ones (none: every view at a frame's posture is paired with it). Two differences from
    one frame share its noise (``Cov(d1, d2) = Sigma_cal`` on their shared points): each paired
    view carries its frame's noise over all the frame's points (``frame``), from which the
    check's covariance takes those blocks (without them 3 / 5 new views at one posture all
    paired gave 25 % / 50 % false alarms at alpha 0.05 in the unit test's scene)."""
    if not frames:
        return list(views), 0
    at = same_posture(
        np.array([q[f] for f, _, _ in new]), np.asarray(q_frames)[[f for f, _, _ in frames]], tol
    )
    quiet = dataclasses.replace(em, model_error_m=0.0, model_error_rad=0.0)  # it repeats: cancels

    def lin(qv: np.ndarray, Xv: np.ndarray, uvv: np.ndarray) -> ViewJacobians:
        return view_jacobians(quiet, camera, qv, Xv, uvv, eye_to_hand=eye_to_hand,
                              pixel_sigma_px=pixel_sigma_px, joint_sigma_rad=joint_sigma_rad)  # fmt: skip

    whole: dict[int, ViewJacobians] = {}  # each paired frame over all its points
    out = []
    for v, (f, X, uv), i in zip(views, new, at, strict=True):
        if i < 0:
            out.append(v)
            continue
        ia, ib = _shared(X, frames[i][1])
        if len(ia) < MIN_SHARED:
            out.append(v)
            continue
        fc, Xc, uvc = frames[i]
        if i not in whole:
            whole[i] = lin(q_frames[fc], Xc, uvc)
        a, b = lin(q[f], X[ia], uv[ia]), whole[i]
        rows = np.stack([2 * ib, 2 * ib + 1], axis=1).reshape(-1)
        d = a.r - b.r[rows]
        extra, own, frame_px = _own_noise(a, d, b.r[rows], pixel_sigma_px, white_level(len(new)))
        out.append(dataclasses.replace(a, r=d, paired=True, own_px=own, frame_px=frame_px,
                                       local=a.local + b.local[np.ix_(rows, rows)] + extra,
                                       frame=(int(i), rows, b.local),
                                       frame_H=np.concatenate([b.kin, b.cam], axis=1)[rows]))  # fmt: skip
    return out, 0


def _own_noise(a: ViewJacobians, d: np.ndarray, frame_r: np.ndarray, white_px: float,
               level: float) -> tuple[np.ndarray | float, Px, Px]:  # fmt: skip
    """For the paired difference ``d`` (2k,) px of the new view ``a`` from its frame (whose
    residuals on the same rows are ``frame_r`` (2k,) px): its covariance's extra white noise
    (2k, 2k) px^2 (0.0 for none), ``own_px`` and ``frame_px``
    (:class:`selfcal.calibration.drift.views.ViewJacobians`). Where ``d`` outside the view's
    pose span and the camera's directions shows more than two exposures of the calibration's
    white noise ``white_px`` (:func:`selfcal.calibration.drift.views.view_white_px` at
    ``sqrt(2) white_px`` and the check's ``level`` a view), the excess is one image's or
    both's. The frame's own residuals there tell which: a frame as noisy as the calibration's
    leaves the excess to the new image (``own_px``, its noise beside the calibration's), a
    noisy view, as an unpaired view noisier than the frames; a frame above the calibration's
    (at ``level``) is named (``frame_px``: the calibration's image at that posture is the noisy
    one, which no new image helps), and the new image is noisy too only where ``d`` shows
    more there than the frame's residuals and the calibration's noise together
    (:func:`_new_noisier`; its own the difference's less the frame's). Measured on the
    difference, not on the new view's residuals alone: what repeats at the posture (a lens term
    the calibration holds) cancels there, so a re-exposure as noisy as its frame is not noisy,
    while a change since the calibration that the check does not model, or a noisier new image,
    is (review of session 25: a noisy frame's excess was given to the new image, whose
    verdict then named a sharp image noisy)."""
    w = view_white_px(d, a.tool, a.cam, np.sqrt(2.0) * white_px, level)
    if w is None:
        return 0.0, None, None
    extra = (w**2 - 2.0 * white_px**2) * np.eye(len(d))
    c = view_white_px(frame_r, a.tool, a.cam, white_px, level)
    if c is None:  # the frame as noisy as the calibration's: the excess is the new image's
        return extra, (float(np.sqrt(w**2 - white_px**2)), float(white_px)), None
    frame = (float(c), float(white_px))
    if not _new_noisier(d, frame_r, a, white_px, level):
        return extra, None, frame
    return extra, (float(np.sqrt(max(w**2 - c**2, white_px**2))), float(white_px)), frame


def _new_noisier(d: np.ndarray, frame_r: np.ndarray, a: ViewJacobians, white_px: float,
                 level: float) -> bool:  # fmt: skip
    """Does the paired difference ``d`` = new - frame (2k,) px show more than the frame's
    residuals ``frame_r`` (2k,) px and the calibration's white noise ``white_px`` together,
    outside the new view ``a``'s pose span and the camera's directions, at ``level``? There,
    given the frame's noise ``e`` (its residuals projected), ``|P d|^2 / white_px^2`` of a new
    image with the calibration's noise is non-central chi-square with the degrees of freedom
    and ``|P e|^2 / white_px^2``."""
    Q = span_basis(np.concatenate([a.tool, a.cam], axis=1))
    dof = len(d) - Q.shape[1]
    e_d, e_f = d - Q @ (Q.T @ d), frame_r - Q @ (Q.T @ frame_r)
    return bool(e_d @ e_d > white_px**2 * ncx2.isf(level, dof, e_f @ e_f / white_px**2))


def paired_views(cal: BoardCalibrationResult, path: Path, held: HeldOutViews,
                 mine: HeldOutViews | None, new: list[tuple[int, np.ndarray, np.ndarray]],
                 tested: list[ViewJacobians], *, em: ToolErrorModel,
                 noise: Noise) -> tuple[list[ViewJacobians], int]:  # fmt: skip
    """The check's pairing (:func:`selfcal.calibration.drift.images.check_images`): the new
    views ``tested`` (of ``new``, frames into ``held.q``) at the postures of the frames of the
    calibration ``cal`` (file ``path``; ``mine`` its dataset's views,
    :func:`selfcal.calibration.drift.own.calibration_frames`) each against its frame
    (:func:`pair_views`) when its frames showed a per-view misfit (``noise``, the check's
    :class:`selfcal.calibration.drift.images.ViewNoise`: ``misfit_counted``), and how
    many further views at a paired posture were tested as new. Warns (SelfCalWarning) when
    such views are at its postures but its dataset is not beside ``path`` to pair them with."""
    if not noise.misfit_counted:
        return list(tested), 0
    pixel_sigma_px, joint_sigma_rad = noise.pixel_sigma_px, noise.joint_sigma_rad
    q_cal = board_postures_from_json(cal.accuracy or {}, cal.model.n, str(path))
    tol = posture_tol(joint_sigma_rad, cal.model.n)
    if mine is None:
        near = same_posture(np.array([held.q[f] for f, _, _ in new]), q_cal, tol) >= 0
        if np.any(near) and calibration_dataset(path) is None:
            warnings.warn(
                f"{np.count_nonzero(near)} image(s) at the calibration's postures not paired: "
                f"its dataset is not beside {path} (they are tested as new images, which counts "
                "the misfit that repeats at a posture as a change); fix: put the calibration's "
                f"dataset (its dataset.json and images) in {path.parent}",
                SelfCalWarning,
                stacklevel=3,
            )
        return list(tested), 0
    frames = [(f, X, uv) for _, f, _, _, X, uv in mine.views
              if np.any(np.all(np.abs(q_cal - mine.q[f]) <= JOINT_TOL, axis=1))]  # fmt: skip
    return _pair(tested, new, held.q, frames, mine.q, em=em, camera=cal.cameras[0],
                 eye_to_hand=cal.eye_to_hand, pixel_sigma_px=pixel_sigma_px,
                 joint_sigma_rad=joint_sigma_rad, tol=tol)  # fmt: skip


def noise_covariance(cal: BoardCalibrationResult, em: ToolErrorModel) -> np.ndarray | None:
    """(p + c, p + c) the part of the check's estimate covariance
    (:func:`selfcal.calibration.drift.covariance.estimate_covariance`, in its order) from the
    calibration frames' noise alone (the ``accuracy`` block's ``noise_covariance_si``: no held
    deviation, no model error): what a paired frame's noise shares with the estimate (module
    docstring); None for a file written before it (the cross term is then left out).

    Raises:
        InputError: the key is there but not a (p + c, p + c) matrix (named, with the fix).
    """
    p, c = len(em.covariance), len(cal.cameras[0].free)
    value = (cal.accuracy or {}).get("noise_covariance_si")
    if value is None:
        return None
    try:
        C = np.asarray(value, float)
    except (TypeError, ValueError):
        C = np.empty(0)
    if C.shape != (p + c, p + c):
        raise InputError(
            f"calibration.json: accuracy.noise_covariance_si is not a {p + c} x {p + c} matrix "
            f"(the error model's {p} parameters and the camera's {c} free ones; its shape is "
            f"{C.shape if C.size else 'not a matrix'})",
            fix="re-run `selfcal calibrate` on the calibration's dataset",
        )
    return C
