"""Benchmark: the held parameters' deviation against the per-view misfit in a real calibration's
drift check (issue #29, docs/real-data.md).

The check's prediction of a view (:mod:`selfcal.calibration.drift.images`) carries the share of
the held parameters' deviation from the drawing that the calibration's folds show
(:mod:`selfcal.calibration.board.held_prior`, in the estimate's covariance ``C``, one error
shared by every view) and the per-view misfit its own frames show
(:mod:`selfcal.calibration.board.view_jitter`, estimated from their residuals, which the
deviation leaves too). This splits ``C`` into its Cramer-Rao part and the deviation's (the
calibration's dataset is calibrated again: ``calibration.json`` stores them summed) and prints,
per dataset, each one's energy per corner (px^2) in the views' pose spans at the share used
(its upper confidence bound) and at the folds' point estimate, beside the residuals' there;
then the check's p-value on the new views as it is, with the deviation left out of ``C``, with
the per-view misfit estimated net of what the deviation leaves in the calibration's frames, and
with the share at its point estimate.

Run: ``uv run python -m selfcal.benchmarks.drift.real_deviation CAL NEW`` (CAL the folder of
``selfcal calibrate``, NEW a folder of ``selfcal import``; the real tier's, docs/real-data.md).
Minutes: the calibration runs again.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.bounds import BoardCramerRao
from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.held_prior import with_deviation
from selfcal.calibration.board.view_jitter import psd_part
from selfcal.calibration.drift.images import (
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    image_drift_check,
    view_noise,
)
from selfcal.calibration.drift.views import ViewJacobians
from selfcal.io.board_calibration import BoardCalibrationResult, read_board_calibration
from selfcal.threads import limit_threads

__all__ = ["deviation_covariance", "deviation_part", "main", "with_share"]


def with_share(cr: BoardCramerRao, share: float) -> np.ndarray:
    """(k + c, k + c) the estimate covariance of the bounds ``cr`` with the deviation at the
    ``share`` of :class:`Deviation`'s prior (every minimal parameter, then the first camera's
    free ones: ``estimate_covariance``'s order; SI)."""
    b = with_deviation(cr, share * Deviation().variance(cr.model.joint_types))
    assert b.camera_covariance is not None and b.camera_cross is not None
    return np.block([[b.covariance, b.camera_cross], [b.camera_cross.T, b.camera_covariance]])


def deviation_part(cr: BoardCramerRao, share: float) -> np.ndarray:
    """The deviation's part of :func:`with_share` (SI)."""
    return with_share(cr, share) - with_share(cr, 0.0)


def deviation_covariance(cal_dir: Path, share: float) -> np.ndarray:
    """:func:`deviation_part` of the calibration of ``cal_dir`` run again."""
    cr = calibrate_board_dataset_detailed(cal_dir).cramer_rao
    if cr is None:
        raise SystemExit(f"{cal_dir}: no Cramer-Rao bounds")
    return deviation_part(cr, share)


def _in_pose_span(views: list[ViewJacobians], M: np.ndarray) -> float:
    """The energy per corner (px^2) of the estimate covariance ``M`` in the views' pose spans."""
    out = 0.0
    for v in views:
        H = np.concatenate([v.kin, v.cam], axis=1)
        out += float(np.trace(v.tool @ np.linalg.pinv(v.tool) @ H @ M @ H.T))
    return out / (sum(len(v.r) for v in views) / 2)


def _measured(views: list[ViewJacobians]) -> float:
    """The residuals' energy per corner (px^2) in the views' pose spans."""
    out = sum(float(v.r @ v.tool @ np.linalg.pinv(v.tool) @ v.r) for v in views)
    return out / (sum(len(v.r) for v in views) / 2)


def _net_misfit(cal: BoardCalibrationResult, own: list[ViewJacobians], V: np.ndarray,
                new: list[ViewJacobians]) -> list[ViewJacobians]:  # fmt: skip
    """``new`` with the per-view misfit in the pose span estimated net of the deviation's part
    ``V`` in the calibration's ``own`` frames (the jitter's mean, or the misfit per pose
    direction, whichever the calibration carries)."""
    noise = view_noise(cal)
    w2 = noise.pixel_sigma_px**2
    js2 = 0.0 if noise.joint_sigma_rad is None else noise.joint_sigma_rad**2
    S, excess = [], 0.0
    for v in own:
        A = v.tool
        H = np.concatenate([v.kin, v.cam], axis=1)
        Ap = np.linalg.pinv(A)
        D = Ap @ H @ V @ H.T @ Ap.T
        xi = Ap @ v.r
        S.append(np.outer(xi, xi) - w2 * np.linalg.inv(A.T @ A) - (v.tw * js2) @ v.tw.T - D)
        excess += float(v.r @ A @ xi) - 6 * w2 - float(np.sum((A @ v.tw) ** 2 * js2))
        excess -= float(np.trace(A @ D @ A.T))
    out = []
    for v in new:
        A = v.tool
        if noise.jitter is not None:
            old = A @ noise.jitter @ A.T
            added = A @ psd_part(np.mean(S, axis=0)) @ A.T
        else:
            P = A @ np.linalg.pinv(A)
            old = noise.pose_misfit_px**2 * P
            added = max(excess / (6 * len(own)), 0.0) * P
        out.append(dataclasses.replace(v, local=v.local - old + added))
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the split and the p-values (module docstring)."""
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("calibration", type=Path, help="the folder of `selfcal calibrate`")
    ap.add_argument("new", type=Path, help="a folder of `selfcal import`: new views")
    args = ap.parse_args(argv)
    limit_threads(1)
    path = args.calibration / "calibration.json"
    cal = read_board_calibration(path)
    em = calibration_error_model(cal, str(path))
    C = estimate_covariance(cal, em)
    held = (cal.accuracy or {})["held_deviation"]
    used, point = float(held["share"]), held.get("share_estimate")
    V = deviation_covariance(args.calibration, used)
    scale = 1.0 if point is None or used <= 0 else max(float(point), 0.0) / used

    def views(ds: Path) -> list[ViewJacobians]:
        h = held_out_views(cal, ds, cameras=(cal.camera_names[0],))
        return calibration_views(cal, em, h.q, [(f, X, uv) for _, f, _, _, X, uv in h.views])

    own, new = views(args.calibration), views(args.new)
    print(f"share used {used:.4g}, the folds' point estimate {point}")
    print("energy per corner in the pose spans (px^2): Cramer-Rao / deviation at the share used"
          " / at the point estimate / measured")  # fmt: skip
    for name, vs in (("calibration's frames", own), (str(args.new), new)):
        print(f"  {name}: {_in_pose_span(vs, C - V):.3f} / {_in_pose_span(vs, V):.3f} / "
              f"{scale * _in_pose_span(vs, V):.3f} / {_measured(vs):.3f}")  # fmt: skip
    for label, Cx, vs in (
        ("as it is", C, new),
        ("the deviation left out", C - V, new),
        ("the misfit net of the deviation", C, _net_misfit(cal, own, V, new)),
        ("the share at its point estimate", C - (1 - scale) * V, new),
    ):
        res = image_drift_check(Cx, vs, eye_to_hand=cal.eye_to_hand,
                                camera_names=cal.cameras[0].free)  # fmt: skip
        print(f"  {label}: p = {res.p_value:.2g}, predicted/measured RMS "
              f"{res.expected_rms_px / res.rms_px:.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
