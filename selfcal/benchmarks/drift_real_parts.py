"""Benchmark: what ``selfcal check`` predicts for new images of a real calibration, part by part,
against what they show (issue #29).

The check's covariance of a view's residuals (:mod:`selfcal.calibration.drift.images`) is a sum
of parts: the calibration's estimate carried to the view (``H C H^T``), the model error and the
joint read-back, the per-view misfit in the pose span (``g^2 P``, ``P`` the projection on the
span of the view's 6 pose columns; ``A J A^T``, the pose jitter, in a file written before
``pose_misfit_px``), the per-view misfit in the camera's directions (``c^2 U U^T``) and the white corner noise (``s^2 I``;
:func:`selfcal.calibration.drift.images.view_noise`). Per dataset given (the calibration's own,
the held-out one) this prints each part's predicted energy per corner (px^2, both coordinates)
in three orthogonal subspaces of each view, beside the residuals' own energy there: the span of
the view's 6 pose columns ``A``, the camera's directions outside it (``U``,
:func:`selfcal.calibration.board.view_jitter.camera_directions`) and the rest; then the
predicted and measured 2-D RMS, their ratio and the check's verdict. Residuals of the
calibration's own frames are fitted ones (smaller than a new view's by what the fit absorbed).

Run: ``uv run python -m selfcal.benchmarks.drift_real_parts CAL DATASET [DATASET ...]`` (CAL the
folder of ``selfcal calibrate`` or its calibration.json; each DATASET a folder of ``selfcal
import``), e.g. on the real tier's sets after ``uv run pytest -m real`` has imported and
calibrated them (docs/real-data.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.view_jitter import camera_directions
from selfcal.calibration.drift.images import (
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    image_drift_check,
    view_noise,
)
from selfcal.io.board_calibration import read_board_calibration
from selfcal.threads import limit_threads

__all__ = ["PARTS", "SPACES", "main", "parts"]

PARTS = ("estimate", "model error and joints", "pose misfit", "camera misfit", "white noise")
SPACES = ("pose span", "camera directions", "rest")


def parts(calibration: Path, dataset: Path) -> dict:
    """Per part of the check's covariance (:data:`PARTS`) and for the residuals (``measured``):
    the energy per corner (px^2) in each subspace (:data:`SPACES`) over the ``dataset``'s views
    of the first camera; ``corners``; ``check``: the check's verdict line."""
    path = calibration / "calibration.json" if calibration.is_dir() else calibration
    cal = read_board_calibration(path)
    em = calibration_error_model(cal, str(path))
    C = estimate_covariance(cal, em)
    noise = view_noise(cal, str(path))
    held = held_out_views(cal, dataset, cameras=(cal.camera_names[0],))
    views = calibration_views(cal, em, held.q, [(f, X, uv) for _, f, _, _, X, uv in held.views])
    out = {key: dict.fromkeys(SPACES, 0.0) for key in (*PARTS, "measured")}
    for v in views:
        n2 = len(v.r)
        H = np.concatenate([v.kin, v.cam], axis=1)
        P = v.tool @ np.linalg.pinv(v.tool)
        U = camera_directions(v.tool, v.cam)
        Pc = U @ U.T
        J = np.zeros((6, 6)) if noise.jitter is None else noise.jitter
        jit = v.tool @ J @ v.tool.T + noise.pose_misfit_px**2 * P
        cam = noise.camera_misfit_px**2 * Pc
        white = noise.pixel_sigma_px**2 * np.eye(n2)
        blocks = {
            "estimate": H @ C @ H.T,
            "model error and joints": v.local - jit - cam - white,
            "pose misfit": jit,
            "camera misfit": cam,
            "white noise": white,
            "measured": np.outer(v.r, v.r),
        }
        for key, B in blocks.items():
            pose, camd = float(np.trace(P @ B)), float(np.trace(Pc @ B))
            out[key]["pose span"] += pose
            out[key]["camera directions"] += camd
            out[key]["rest"] += float(np.trace(B)) - pose - camd
    corners = sum(len(v.r) for v in views) // 2
    for row in out.values():
        for space in SPACES:
            row[space] /= corners
    out["corners"] = corners
    out["check"] = image_drift_check(C, views, eye_to_hand=cal.eye_to_hand,
                                     camera_names=cal.cameras[0].free).line()  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the parts (module docstring) per dataset."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("calibration", type=Path)
    ap.add_argument("datasets", type=Path, nargs="+")
    args = ap.parse_args(argv)
    limit_threads(1)
    for ds in args.datasets:
        res = parts(args.calibration, ds)
        print(f"{ds}: {res['corners']} corners; energy per corner (px^2)")
        print(f"  {'part':24s}" + "".join(f"{s:>19s}" for s in SPACES) + f"{'total':>10s}")
        for key in (*PARTS, "measured"):
            row = res[key]
            print(f"  {key:24s}" + "".join(f"{row[s]:19.4f}" for s in SPACES)
                  + f"{sum(row.values()):10.4f}")  # fmt: skip
        pred = sum(sum(res[k].values()) for k in PARTS)
        meas = sum(res["measured"].values())
        print(f"  predicted 2-D RMS {np.sqrt(pred):.3f} px, measured {np.sqrt(meas):.3f} px, "
              f"ratio {np.sqrt(pred / meas):.2f}; check: {res['check']}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
