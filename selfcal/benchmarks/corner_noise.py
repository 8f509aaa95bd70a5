"""The detector's corner noise on a simulated board or field dataset, measured against the truth.

For the rendered board benchmarks (:mod:`selfcal.benchmarks.board.accuracy` ``--render``):
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

__all__ = [
    "CornerNoise",
    "corner_errors",
    "corner_noise",
    "corner_stats",
    "field_corner_noise",
    "marker_centre_sigma",
    "marker_shape_sigma",
]


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
    centre_sigma_px: float | None = None
    """:func:`field_corner_noise`'s markers: twice the RMS per coordinate of each detected
    marker's mean corner error, its centre's (every corner within the floor; None for a
    board): the white corner noise whose marker centres err as much. A rendered marker's four
    corners err together less than white noise of ``sigma_px`` makes them (most of their error
    moves the corners against each other; issue #30, docs/plan.md "What the rendered draws gain
    over the forecast")."""
    shape_sigma_px: float | None = None
    """The same markers' corners' errors less their mean, as a noise level per coordinate of
    the six coordinates of a marker's shape (:func:`marker_shape_sigma`; None for a board):
    with :attr:`centre_sigma_px` the noise of
    :func:`selfcal.calibration.field.bounds_split.split_tool_rms`."""

    def to_json(self) -> dict:
        """Plain numbers for a benchmark's row."""
        out: dict[str, float | int | None] = {
               "count": self.count, "mean_u_px": self.mean_px[0], "mean_v_px": self.mean_px[1],
               "sigma_px": self.sigma_px, "rms_px": self.rms_px, "p99_px": self.p99_px,
               "outliers": self.outliers}  # fmt: skip
        if self.centre_sigma_px is not None:
            out["centre_sigma_px"] = self.centre_sigma_px
            out["shape_sigma_px"] = self.shape_sigma_px
        return out


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


def _noise(d: np.ndarray, outliers: int = 0, markers: np.ndarray | None = None) -> CornerNoise:
    """The :class:`CornerNoise` of detected minus true corners ``d`` (k, 2) px (``markers``:
    the errors (M, 4, 2) px of the markers whose corners are all kept, for the centres' and
    shapes' noise)."""
    mean = d.mean(axis=0)
    return CornerNoise(
        count=len(d),
        mean_px=(float(mean[0]), float(mean[1])),
        sigma_px=float(np.sqrt(np.mean((d - mean) ** 2))),
        rms_px=float(np.sqrt(np.mean(d**2))),
        p99_px=float(np.percentile(np.linalg.norm(d, axis=1), 99)),
        outliers=outliers,
        centre_sigma_px=None if markers is None else marker_centre_sigma(markers),
        shape_sigma_px=None if markers is None else marker_shape_sigma(markers),
    )


def marker_centre_sigma(d: np.ndarray) -> float:
    """Twice the RMS per coordinate (px) of the mean of each marker's four corner errors ``d``
    (M, 4, 2) px: for independent corner noise of ``s`` px per coordinate it is ``s``, and
    errors that move a marker's corners against each other (their mean zero) add nothing
    (:attr:`CornerNoise.centre_sigma_px`).

    Raises:
        InternalError: ``d`` is not (M, 4, 2) with M > 0.
    """
    return float(2.0 * np.sqrt(np.mean(_markers(d).mean(axis=1) ** 2)))


def marker_shape_sigma(d: np.ndarray) -> float:
    """The RMS (px) of each marker's corner errors ``d`` (M, 4, 2) px less their mean, per
    coordinate of the six a marker's shape has (the eight less its centre's two): for
    independent corner noise of ``s`` px per coordinate it is ``s``; a shared shift adds nothing.

    Raises:
        InternalError: ``d`` is not (M, 4, 2) with M > 0.
    """
    d = _markers(d)
    rest = d - d.mean(axis=1, keepdims=True)
    return float(np.sqrt(np.sum(rest**2) / (6.0 * len(d))))


def _markers(d: np.ndarray) -> np.ndarray:
    """``d`` as (M, 4, 2) float.

    Raises:
        InternalError: ``d`` is not (M, 4, 2) with M > 0.
    """
    d = np.asarray(d, dtype=float)
    if d.ndim != 3 or d.shape[1:] != (4, 2) or len(d) == 0:
        raise InternalError(f"marker corner errors of shape {d.shape}, not (M, 4, 2)")
    return d


def field_corner_noise(root: Path) -> CornerNoise:
    """The marker corners the field route detects in the images of the simulated field dataset
    ``root`` (its first camera, :func:`selfcal.calibration.field.detections.detect_dataset`)
    against the true marker corners projected by the true camera at each frame's true pose
    (``root/truth.json``). Corners farther from the truth than the route's outlier floor
    (:data:`selfcal.calibration.field.adjust.OUTLIER_FLOOR_PX`: a marker partly hidden, which
    the calibration rejects) are counted in ``outliers`` and left out of the figures, so the
    sigma is the noise of the corners a calibration keeps; the markers whose four corners are
    all kept give :attr:`CornerNoise.centre_sigma_px` (:func:`marker_centre_sigma`).

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
    out = [np.zeros((0, 4, 2))]
    for (index, name), found in detect_dataset(ds).detections.items():
        fr = truth.frame(int(index))
        if name != cam or fr is None or not found:
            continue
        T = inv_pose(fr.T_world_cam_left)
        for mid, uv in found.items():
            X = corners[int(mid)] @ T[:3, :3].T + T[:3, 3]
            e = np.asarray(uv, dtype=float).reshape(4, 2) - truth.intrinsics_left.project(X)
            out.append(e[None])
    m = np.concatenate(out)  # (markers, 4, 2)
    if len(m) == 0:
        raise InternalError(f"{root}: no marker corner detected to compare with the truth")
    near = np.linalg.norm(m, axis=2) <= OUTLIER_FLOOR_PX
    whole = near.all(axis=1)
    return _noise(m[near], outliers=int(np.sum(~near)), markers=m[whole] if whole.any() else None)


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
