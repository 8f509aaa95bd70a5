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

``--frames``: how the calibration's own frames' pose errors ``xi_i`` carry to one another
(:mod:`selfcal.calibration.board.view_jitter`): the frame whose ``xi_i`` carried to every frame
(``A_j xi_i``) gives them the most energy, and each frame's pose-span energy predicted from the
other frames by the jitter's mean and by a misfit per pose direction, against its own.

Run: ``uv run python -m selfcal.benchmarks.drift.real_parts CAL DATASET [DATASET ...]`` (CAL the
folder of ``selfcal calibrate`` or its calibration.json; each DATASET a folder of ``selfcal
import``), e.g. on the real tier's sets after ``uv run pytest -m real`` has imported and
calibrated them (docs/real-data.md).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.view_jitter import camera_directions, psd_part
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
    out: dict[str, Any] = {key: dict.fromkeys(SPACES, 0.0) for key in (*PARTS, "measured")}
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


def carried(calibration: Path) -> dict:
    """The ``--frames`` figures (module docstring) on the calibration's own frames (energy per
    corner, px^2, the pose spans only): ``frame`` the index whose pose error carried to all
    frames gives the most, ``own`` its own, ``carried`` what it gives them (mean per corner);
    ``mean_ratio`` and ``direction_ratio``: every frame's predicted from the others by the
    jitter's mean and by the misfit per pose direction, summed, over their own summed."""
    path = calibration / "calibration.json" if calibration.is_dir() else calibration
    cal = read_board_calibration(path)
    em = calibration_error_model(cal, str(path))
    noise = view_noise(cal, str(path))
    folder = path.parent
    held = held_out_views(cal, folder, cameras=(cal.camera_names[0],))
    views = calibration_views(cal, em, held.q, [(f, X, uv) for _, f, _, _, X, uv in held.views])
    w2 = noise.pixel_sigma_px**2
    js2 = 0.0 if noise.joint_sigma_rad is None else noise.joint_sigma_rad**2
    A = [v.tool for v in views]
    k = np.array([len(v.r) / 2 for v in views])
    xi = [np.linalg.pinv(a) @ v.r for a, v in zip(A, views, strict=True)]
    own = np.array([float(x @ a.T @ a @ x) for x, a in zip(xi, A, strict=True)])
    S = [np.outer(x, x) - w2 * np.linalg.inv(a.T @ a) - (v.tw * js2) @ v.tw.T
         for x, a, v in zip(xi, A, views, strict=True)]  # fmt: skip
    excess = own - 6 * w2 - np.array([float(np.sum((a @ v.tw) ** 2 * js2))
                                      for a, v in zip(A, views, strict=True)])  # fmt: skip
    E = np.array([[float(x @ a.T @ a @ x) / kj for x in xi] for a, kj in zip(A, k, strict=True)])
    top = int(np.argmax(E.mean(axis=0)))
    n, mean_pred, dir_pred = len(views), 0.0, 0.0
    for i, a in enumerate(A):
        J = psd_part((np.sum(S, axis=0) - S[i]) / (n - 1))
        mean_pred += float(np.trace(a @ J @ a.T))
        dir_pred += 6 * max((excess.sum() - excess[i]) / (6 * (n - 1)), 0.0)
    return {"frame": top, "own": float(own[top] / k[top]), "carried": float(E[:, top].mean()),
            "mean_ratio": mean_pred / own.sum(), "direction_ratio": dir_pred / own.sum()}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Print the parts (module docstring) per dataset."""
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("calibration", type=Path)
    ap.add_argument("datasets", type=Path, nargs="+")
    ap.add_argument("--frames", action="store_true",
                    help="also how the calibration's own frames' pose errors carry to one "
                    "another (module docstring)")  # fmt: skip
    args = ap.parse_args(argv)
    limit_threads(1)
    if args.frames:
        c = carried(args.calibration)
        print(f"calibration's frames: frame {c['frame']}'s pose error ({c['own']:.3f} px^2 per "
              f"corner in its own pose span) carried to every frame gives {c['carried']:.3f}; "
              f"each frame predicted from the others / its own: the jitter's mean "
              f"{c['mean_ratio']:.2f}, a misfit per pose direction {c['direction_ratio']:.2f}")  # fmt: skip
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
