"""Which new views are the calibration's own frames (the drift check, issue #29)?

A board calibration's own frames cannot show a change it absorbed: their residuals are its
fit's, made orthogonal by the fit (equal weights, the poses from the chain at the joint
readings) to every change it estimated, the camera's, the mounts' and the joints' offsets. The
check's test assumes new views independent of the calibration's estimate and weighs them by
their own covariance (the per-view misfit in the pose span, the camera's directions): in that
metric the fit's residuals are no longer orthogonal to the candidates, and its directed tests
read the difference between the two metrics' fits as a change (the real photoneo set checked
against its own images: the camera's test p = 8.4e-5, a camera change "fx +1.727" where nothing
changed, while the omnibus statistic is 3425 on 3520 degrees of freedom). Under the right
null, the fit's residuals' covariance, those directions carry nothing at all, and what is left
(the residual space) is what the calibration's noise levels were estimated from. So the check
leaves such views out of the test and says how many it left out.

A new view is the calibration's own when a frame of the calibration's dataset (the folder
``selfcal calibrate`` wrote ``calibration.json`` into) has the same joint readings (within
:data:`JOINT_TOL`) and the same board detections (the same board points, the pixels within
:data:`UV_TOL`): by content, not by file name, so a copy, a re-export or renamed images are
found the same. A new exposure at a posture the arm repeats exactly differs in its pixels by
the corner noise (0.02 px and more), far above :data:`UV_TOL`. Only frames at the
calibration's own postures (its ``accuracy`` block's) count: a dataset beside the file that is
not the one it calibrated has none of its frames.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from selfcal.calibration.board.accuracy import board_postures_from_json
from selfcal.calibration.board.evaluate import HeldOutViews, held_out_views
from selfcal.errors import SelfCalError, SelfCalWarning
from selfcal.io.board_calibration import BoardCalibrationResult

__all__ = ["JOINT_TOL", "UV_TOL", "calibration_dataset", "calibration_frames", "own_views"]

JOINT_TOL = 1e-6
"""rad / m: joint readings this close are the same reading (a CSV round trip in degrees with six
decimals moves them by up to 1e-8 rad)."""
UV_TOL = 1e-3
"""px: detections this close are the same detection (a re-detection of the same image is
identical; a new image's corner noise is 0.02 px and more)."""


def calibration_dataset(path: Path) -> Path | None:
    """The dataset folder of the calibration file ``path`` (``calibration.json`` in the folder
    ``selfcal calibrate`` read and wrote it into), or None when no dataset lies beside it."""
    root = path.parent
    return root if (root / "dataset.json").is_file() else None


def _same(a: tuple, b: tuple, qa: np.ndarray, qb: np.ndarray) -> bool:
    """Two views (:class:`HeldOutViews` entries) of joints ``qa`` and ``qb``: the same reading
    and detection?"""
    _, fa, _, _, Xa, uva = a
    _, fb, _, _, Xb, uvb = b
    return (
        Xa.shape == Xb.shape
        and bool(np.all(np.abs(qa[fa] - qb[fb]) <= JOINT_TOL))
        and bool(np.array_equal(Xa, Xb))
        and bool(np.all(np.abs(np.asarray(uva) - np.asarray(uvb)) <= UV_TOL))
    )


def _posed(q_cal: np.ndarray, q: np.ndarray, tol: float | np.ndarray) -> bool:
    """Is ``q`` (n,) one of the postures ``q_cal`` (m, n), every joint within ``tol`` (a number
    or (n,) per joint)?"""
    return bool(np.any(np.all(np.abs(q_cal - q) <= tol, axis=1)))


def calibration_frames(cal: BoardCalibrationResult, path: Path, held: HeldOutViews, camera: str,
                       tol: float | np.ndarray = JOINT_TOL) -> HeldOutViews | None:  # fmt: skip
    """The views (of ``camera``) of the dataset the calibration ``cal`` (its file ``path``)
    calibrated, read when a new view of ``held`` is at one of its postures (its ``accuracy``
    block's: every joint within ``tol``, rad / m, a number or (n,) per joint); None when none
    is or no dataset lies beside the file (a folder there that is not its dataset: warned,
    None)."""
    # only views at the calibration's own postures can be its frames or share their misfit:
    # without one the check reads nothing more (the calibration's images are not detected)
    q_cal = board_postures_from_json(cal.accuracy or {}, cal.model.n, str(path))
    root = calibration_dataset(path)
    if root is None or not any(_posed(q_cal, held.q[v[1]], tol) for v in held.views):
        return None
    if Path(held.root).resolve() == root.resolve():
        return held  # the same folder: its views were read already
    try:
        with warnings.catch_warnings():  # its images without the board: its own news
            warnings.simplefilter("ignore")
            return held_out_views(cal, root, cameras=(camera,))
    except SelfCalError as exc:  # a folder beside it that is not its dataset (edited, moved)
        warnings.warn(
            f"{root}: not read as the calibration's dataset ({exc}); new images at its "
            "postures are tested as new ones (the calibration's own frames' residuals are the "
            "fit's, which can read as a change)",
            SelfCalWarning,
            stacklevel=2,
        )
        return None


def own_views(cal: BoardCalibrationResult, path: Path, held: HeldOutViews,
              mine: HeldOutViews | None) -> np.ndarray:  # fmt: skip
    """(len(held.views),) bool: which of the new views ``held`` are frames of the calibration
    ``cal`` (its file ``path``) by their joints and detections (module docstring); ``mine``
    the calibration's dataset's views (:func:`calibration_frames`), all False when None."""
    if mine is None:
        return np.zeros(len(held.views), bool)
    q_cal = board_postures_from_json(cal.accuracy or {}, cal.model.n, str(path))
    by_points: dict[int, list[tuple]] = {}
    for v in mine.views:  # a dataset beside the file that it did not calibrate: none of these
        if _posed(q_cal, mine.q[v[1]], JOINT_TOL):
            by_points.setdefault(len(v[4]), []).append(v)
    return np.array([any(_same(v, m, held.q, mine.q) for m in by_points.get(len(v[4]), []))
                     for v in held.views], bool)  # fmt: skip
