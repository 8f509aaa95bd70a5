"""The held-out check of a pose dataset's calibration (``selfcal evaluate CAL POSE_DATASET2``).

Every corner of a held-out pose dataset is predicted from its flange poses alone through the
calibrated and the nominal pose chain (:func:`selfcal.calibration.handeye.calibrate.predict_corners`).
A frame with fewer corners than the board's ``min_features`` is left out (as the board
calibration's held-out check does); a corner a model puts behind its camera is no pixel: it is
counted apart, never averaged (the RMS would be NaN), and the calibrated model doing so is a
failure of the check.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from selfcal.calibration.handeye.calibrate import HandEyeFit, chain_motions, predict_corners
from selfcal.errors import InputError, SelfCalWarning
from selfcal.target.base import Features
from selfcal.target.boards import Board

__all__ = ["HeldOutWarning", "held_out_check"]


class HeldOutWarning(SelfCalWarning):
    """Held-out frames were left out (too few corners of the board)."""


def held_out_check(
    board: Board,
    features: Sequence[Features],
    T_base_flange: np.ndarray,
    setup: str,
    models: Mapping[str, HandEyeFit],
    where: str,
) -> dict:
    """Predict the held-out ``features`` (one per frame, px) from the flange poses
    ``T_base_flange`` (n, 4, 4) m of ``setup`` with each of ``models`` (``nominal`` and
    ``calibrated``); ``where`` names the dataset in messages.

    Returns the evaluation's keys: ``frames`` and ``corners`` used, ``skipped_frames`` (indices
    with fewer than ``board.min_features`` corners), ``held_out_rms_px`` by model (over the
    corners in front of its camera; None when there is none), ``behind_camera`` by model (corner
    counts), ``calibration_better_than_nominal`` and ``failures`` (sentences; the calibrated model
    putting corners behind the camera).

    Raises:
        InputError: no frame shows the board with ``board.min_features`` corners.
    """
    keep = [i for i, f in enumerate(features) if len(f) >= board.min_features]
    skipped = [i for i in range(len(features)) if i not in set(keep)]
    if skipped:
        warnings.warn(f"{where}: the {board.describe()} shows fewer than {board.min_features} "
                      f"corners in {len(skipped)} of {len(features)} held-out frame(s), left out: "
                      f"{', '.join(map(str, skipped[:8]))}", HeldOutWarning, stacklevel=2)  # fmt: skip
    if not keep:
        raise InputError(f"{where}: no held-out frame shows the {board.describe()}",
                         fix="give held-out images that show the board")  # fmt: skip
    feats = [features[i] for i in keep]
    view = np.concatenate([np.full(len(f), k) for k, f in enumerate(feats)])
    pts = board.points(np.concatenate([f.ids for f in feats]))
    uv = np.concatenate([f.uv for f in feats])
    A = chain_motions(setup, np.asarray(T_base_flange)[keep])
    rms: dict[str, float | None] = {}
    behind: dict[str, int] = {}
    for name, m in models.items():
        pred = predict_corners(m.camera, m.X, m.B, A, view, pts)
        front = np.isfinite(pred).all(axis=1)
        behind[name] = int((~front).sum())
        e = np.sum((pred[front] - uv[front]) ** 2, axis=1)
        rms[name] = float(np.sqrt(np.mean(e))) if front.any() else None
    failures = []
    if behind["calibrated"]:
        failures.append(f"the calibrated model puts {behind['calibrated']} of {len(uv)} held-out "
                        f"corners of {where} behind the camera: the calibration is wrong for this "
                        "setup, or the datasets do not show the same robot, camera and board")  # fmt: skip
    cal, nom = rms["calibrated"], rms["nominal"]
    better = (not failures and cal is not None
              and (nom is None or behind["nominal"] > 0 or cal < nom))  # fmt: skip
    return {"frames": len(feats), "corners": len(uv), "skipped_frames": skipped,
            "held_out_rms_px": rms, "behind_camera": behind,
            "calibration_better_than_nominal": bool(better), "failures": failures}  # fmt: skip
