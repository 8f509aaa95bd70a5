"""A real board calibration's folds as new views of the drift check (issue #29, the real drift
benchmark :mod:`selfcal.benchmarks.drift.real_folds`).

Each fold of the calibration (the chosen candidate fitted without one arm configuration,
:func:`selfcal.calibration.board.fold_fits.fold_bounds`: the folds that count, as
the accuracy block's) is a calibration and its held-out frames
new views (:class:`Fold`, :func:`folds_of`): every held-out frame linearised at the fold's fit
(pixels in px, parameters SI, the order of the check's
:func:`selfcal.calibration.drift.images.estimate_covariance`), the calibration's per-view pose
misfit carried to it (:func:`pose_misfit`), the fold's estimate covariance without the held
deviation and the deviation's part at the full prior, the sandwich of its training frames
(:func:`sandwich_excess`) and its held-out frames' flange errors as the accuracy block's folds
read them. The calibration runs again: a minute.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from selfcal.benchmarks.drift.real_deviation import deviation_part, with_share
from selfcal.calibration.board.accuracy import board_error_model, held_out_errors
from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.fold_fits import fold_bounds
from selfcal.calibration.board.held_prior import with_deviation
from selfcal.calibration.board.refine import BoardObservations
from selfcal.calibration.drift.images import ViewNoise, calibration_error_model, view_noise
from selfcal.calibration.drift.views import ViewJacobians, view_jacobians, white_level
from selfcal.camera import CameraModel
from selfcal.kinematics.tool_error import ToolErrorModel

__all__ = ["Fold", "folds_of", "pose_misfit", "sandwich_excess"]


@dataclasses.dataclass(frozen=True)
class Fold:
    """One fold's held-out frames as new views of the fold's fit (px; SI).

    Attributes:
        views: every held-out frame linearised at the fold's fit, its ``local`` covariance
            without the pose misfit (every minimal parameter estimated: ``kin``); misfit: per
            view (2k, 2k) px^2 the calibration's per-view pose misfit carried to it. C0: (P, P)
            the fold's estimate covariance without the deviation; V: its deviation's part at
            the full prior (share 1); excess: (P, P) what the sandwich of its training frames
            adds to ``C0`` (:func:`sandwich_excess`; None when not computed); tool: its held-out
            frames' flange errors as the accuracy block's folds read them
            (:func:`selfcal.calibration.board.accuracy.held_out_errors`; None when not
            computed), what :func:`excess_without` pools.
    """

    views: list[ViewJacobians]
    misfit: list[np.ndarray]
    C0: np.ndarray
    V: np.ndarray
    excess: np.ndarray | None = None
    tool: dict[str, np.ndarray] | None = None

    def at(self, a: float) -> list[ViewJacobians]:
        """The views with the pose misfit scaled by ``a``."""
        return [dataclasses.replace(v, local=v.local + a * M)
                for v, M in zip(self.views, self.misfit, strict=True)]  # fmt: skip


def pose_misfit(noise: ViewNoise, A: np.ndarray) -> np.ndarray:
    """(2k, 2k) px^2 the per-view pose misfit the check adds to a view whose pixels' derivative
    by a body twist of the chain's tool is ``A`` (2k, 6): the jitter ``A J A^T`` or the misfit
    per pose direction ``g^2 P`` (:mod:`selfcal.calibration.board.view_jitter`)."""
    if noise.jitter is not None:
        return A @ noise.jitter @ A.T
    return noise.pose_misfit_px**2 * (A @ np.linalg.pinv(A))


def sandwich_excess(views: list[ViewJacobians], fitted: np.ndarray, s2: float) -> np.ndarray:
    """(P, P) the sandwich ``(H^T H)^-1 H^T L H (H^T H)^-1`` less the white-noise covariance
    ``s2 (H^T H)^-1`` of the least-squares estimate of the ``fitted`` (P,) columns of the
    ``views``' ``[kin, cam]`` (the calibration's own frames, ``H`` their stacked columns, ``L``
    their ``local`` covariances block-diagonal; zero rows and columns for the others): what an
    estimate covariance computed as if every pixel had the white noise ``s2`` (px^2) misses when
    the pixels have the per-view covariance the check gives a view (or counts too much, where it
    is negative)."""
    H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in views])[:, fitted]
    P = np.linalg.pinv(H.T @ H)
    at, HtLH = 0, np.zeros_like(P)
    for v in views:
        Hv = H[at : at + len(v.r)]
        HtLH += Hv.T @ v.local @ Hv
        at += len(v.r)
    idx = np.flatnonzero(fitted)
    out = np.zeros((len(fitted), len(fitted)))
    out[np.ix_(idx, idx)] = P @ HtLH @ P - s2 * P
    return out


def _views(obs: BoardObservations, mask: np.ndarray, em: ToolErrorModel, camera: CameraModel,
           noise: ViewNoise, held: bool) -> list[ViewJacobians]:  # fmt: skip
    """The first camera's inlier frames of ``mask`` linearised at the fold's ``em`` and
    ``camera`` with the calibration's ``noise`` less its pose misfit (:class:`Fold`); ``held``:
    new views, each with its own white noise where larger at the check's level, as the check
    gives them (:func:`selfcal.calibration.drift.views.view_white_px`)."""
    v, f, uv = obs.rows(mask & obs.used)[0]
    level = white_level(len(np.unique(v)))
    return [view_jacobians(em, camera, obs.q[i], obs.board.points(f[v == i]), uv[v == i],
                           eye_to_hand=obs.eye_to_hand, pixel_sigma_px=noise.pixel_sigma_px,
                           joint_sigma_rad=noise.joint_sigma_rad,
                           camera_misfit_px=noise.camera_misfit_px, own_white=held,
                           white_level=level, white_px=noise.white_px)
            for i in np.unique(v)]  # fmt: skip


def folds_of(cal_dir: Path) -> tuple[list[Fold], np.ndarray, np.ndarray]:
    """Every fold of the calibration of ``cal_dir`` (run again; module docstring), the
    deviation's part of the calibration's own estimate covariance at the full prior and the
    sandwich excess of its own frames (:func:`sandwich_excess`; SI, ``estimate_covariance``'s
    order)."""
    det = calibrate_board_dataset_detailed(cal_dir)
    cal, obs, cr = det.result, det.observations, det.cramer_rao
    if obs is None or cr is None or cal.bounds is None or det.fit.nominal is None:
        raise SystemExit(f"{cal_dir}: no Cramer-Rao bounds")
    assert det.fit.selection is not None
    noise = view_noise(cal)
    em_cal = calibration_error_model(cal, str(cal_dir))
    T_tp = em_cal.T_tool_point
    assert T_tp is not None
    var = Deviation().variance(cr.model.joint_types)
    out = []
    for held, fit, fcr in fold_bounds(obs, det.fit.selection, det.fit.nominal.model.joint_offsets,
                                      T_tp, cal.bounds.pixel_sigma_px):  # fmt: skip
        em, _ = board_error_model(with_deviation(fcr, var), T_tp, 0.0, 0.0, None)
        views, train = (_views(obs, mask, em, fit.cameras[0], noise, new)
                        for mask, new in ((held, True), (~held, False)))  # fmt: skip
        if views:
            est = np.ones(len(fcr.covariance), bool) if fcr.estimated is None else fcr.estimated
            fitted = np.r_[est, np.ones(views[0].cam.shape[1], bool)]
            train = [dataclasses.replace(x, local=x.local + pose_misfit(noise, x.tool))
                     for x in train]  # fmt: skip
            out.append(Fold(views, [pose_misfit(noise, x.tool) for x in views],
                            with_share(fcr, 0.0), deviation_part(fcr, 1.0),
                            sandwich_excess(train, fitted, cal.bounds.pixel_sigma_px**2),
                            held_out_errors(obs, fit, held, T_tp, fcr)))  # fmt: skip
    own = [dataclasses.replace(x, local=x.local + pose_misfit(noise, x.tool))
           for x in _views(obs, obs.used, em_cal, cal.cameras[0], noise, False)]  # fmt: skip
    est = np.ones(len(cr.covariance), bool) if cr.estimated is None else cr.estimated
    fitted = np.r_[est, np.ones(own[0].cam.shape[1], bool)]
    return out, deviation_part(cr, 1.0), sandwich_excess(own, fitted, cal.bounds.pixel_sigma_px**2)
