"""The detector's corner noise on a simulated board or field dataset, measured against the truth.

For the rendered board benchmarks (:mod:`selfcal.benchmarks.board_accuracy` ``--render``):
every detected feature of the dataset's first camera against the true projection of the same
board point (the true camera at the frame's true camera pose, the board at the truth's pose),
so the corner noise a row reports is the detector's own, not the calibration's residual (which
also carries the fit). The per-coordinate mean says whether the renderer and detector together
are biased; the RMS about it is the noise the calibration should see.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.calibration.board.dataset import dataset_board, detect_board
from selfcal.errors import InternalError
from selfcal.io.dataset import Dataset
from selfcal.io.truth import Truth, read_truth
from selfcal.target.base import Features
from selfcal.transforms import inv_pose

__all__ = ["CornerNoise", "corner_errors", "corner_noise", "corner_stats", "field_corner_noise"]


@dataclass(frozen=True)
class CornerNoise:
    """Detected minus true corners over a dataset (px, OpenCV image coordinates)."""

    count: int
    """Corners compared."""
    mean_px: tuple[float, float]
    """Mean of (u, v) detected minus true: a bias."""
    sigma_px: float
    """RMS per coordinate about that mean (the noise a calibration sees)."""
    rms_px: float
    """RMS per coordinate of detected minus true (bias included)."""
    p99_px: float
    """99th percentile of the per-corner distance: outlying detections."""
    outliers: int = 0
    """Corners left out of the figures above (:func:`field_corner_noise`: farther than the
    field route's outlier floor from the truth)."""

    def to_json(self) -> dict:
        """Plain numbers for a benchmark's row."""
        return {"count": self.count, "mean_u_px": self.mean_px[0], "mean_v_px": self.mean_px[1],
                "sigma_px": self.sigma_px, "rms_px": self.rms_px, "p99_px": self.p99_px,
                "outliers": self.outliers}  # fmt: skip


def corner_errors(truth: Truth, points: list[np.ndarray], features: list[Features],
                  frames: list[int]) -> np.ndarray:  # fmt: skip
    """(k, 2) px detected minus true corners: ``features[i]`` found in the frame ``frames[i]``
    of ``truth`` at the board points ``points[i]`` ((k_i, 3) m, board frame)."""
    T_world_board = truth.T_world_board
    if T_world_board is None:
        raise InternalError("corner_errors: the truth has no board pose (not a board scenario)")
    out = [np.zeros((0, 2))]
    for X, f, index in zip(points, features, frames, strict=True):
        fr = truth.frame(index)
        if fr is None or len(f) == 0:
            continue
        T = inv_pose(fr.T_world_cam_left) @ T_world_board
        out.append(f.uv - truth.intrinsics_left.project(X @ T[:3, :3].T + T[:3, 3]))
    return np.concatenate(out)


def corner_noise(root: Path) -> CornerNoise:
    """The board features detected in the images of the simulated dataset ``root`` (its first
    camera, as the board route detects them) against their true projections (``root/truth.json``)."""
    ds = Dataset.open(root)
    board = dataset_board(ds)
    feats, _ = detect_board(ds, board, ds.info.cameras[0])
    d = corner_errors(read_truth(root / "truth.json"), [board.points(f.ids) for f in feats],
                      feats, [int(i) for i in ds.indices])  # fmt: skip
    if len(d) == 0:
        raise InternalError(f"{root}: no corner detected to compare with the truth")
    return _noise(d)


def _noise(d: np.ndarray, outliers: int = 0) -> CornerNoise:
    """The :class:`CornerNoise` of detected minus true corners ``d`` (k, 2) px."""
    mean = d.mean(axis=0)
    return CornerNoise(
        count=len(d),
        mean_px=(float(mean[0]), float(mean[1])),
        sigma_px=float(np.sqrt(np.mean((d - mean) ** 2))),
        rms_px=float(np.sqrt(np.mean(d**2))),
        p99_px=float(np.percentile(np.linalg.norm(d, axis=1), 99)),
        outliers=outliers,
    )


def field_corner_noise(root: Path) -> CornerNoise:
    """The marker corners the field route detects in the images of the simulated field dataset
    ``root`` (its first camera, :func:`selfcal.calibration.field.detections.detect_dataset`)
    against the true marker corners projected by the true camera at each frame's true pose
    (``root/truth.json``). Corners farther from the truth than the route's outlier floor
    (:data:`selfcal.calibration.field.adjust.OUTLIER_FLOOR_PX`: a marker partly hidden, which
    the calibration rejects) are counted in ``outliers`` and left out of the figures, so the
    sigma is the noise of the corners a calibration keeps.

    Raises:
        InternalError: the dataset is not a simulated field, or no corner was detected.
    """
    from selfcal.calibration.field.adjust import OUTLIER_FLOOR_PX
    from selfcal.calibration.field.detections import detect_dataset
    from selfcal.sim.markers import MarkerField

    ds = Dataset.open(root)
    truth = read_truth(root / "truth.json")
    if truth.marker_field is None:
        raise InternalError(f"{root}: the truth has no marker field (not a field scenario)")
    field = MarkerField.from_dict(truth.marker_field)
    corners = dict(zip(field.ids.tolist(), field.corners_world(), strict=True))
    cam = ds.info.cameras[0]
    out = [np.zeros((0, 2))]
    for (index, name), found in detect_dataset(ds).detections.items():
        fr = truth.frame(int(index))
        if name != cam or fr is None or not found:
            continue
        T = inv_pose(fr.T_world_cam_left)
        for mid, uv in found.items():
            X = corners[int(mid)] @ T[:3, :3].T + T[:3, 3]
            out.append(np.asarray(uv, dtype=float).reshape(4, 2) - truth.intrinsics_left.project(X))
    d = np.concatenate(out)
    if len(d) == 0:
        raise InternalError(f"{root}: no marker corner detected to compare with the truth")
    near = np.linalg.norm(d, axis=1) <= OUTLIER_FLOOR_PX
    return _noise(d[near], outliers=int(np.sum(~near)))


def corner_stats(c: list[dict]) -> dict:
    """A benchmark row's corner noise over its draws' :meth:`CornerNoise.to_json` ``c`` (px):
    the median and the largest draw's sigma, the largest absolute mean (bias) and the median
    99th percentile distance; none without draws."""
    if not c:
        return {}
    sig = [x["sigma_px"] for x in c]
    bias = max(max(abs(x["mean_u_px"]), abs(x["mean_v_px"])) for x in c)
    return {"corner_sigma_px": float(np.median(sig)), "corner_sigma_max_px": float(max(sig)),
            "corner_bias_px": float(bias),
            "corner_p99_px": float(np.median([x["p99_px"] for x in c]))}  # fmt: skip
