"""The import's check of the declared board against the detections (selfcal/importing/dataset.py
check_geometry): a wrong board is refused naming the target file; a strongly distorting lens
(which the pinhole board calibration alone would take for a wrong board) is not."""

from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest

from selfcal.calibration.board.calibrate import BoardMismatchError, calibrate_board
from selfcal.importing.dataset import check_geometry
from selfcal.target import Charuco, Features
from selfcal.target.board_views import random_board_poses

K = np.array([[800.0, 0, 331.5], [0, 800.0, 231.5], [0, 0, 1]])
PRINTED = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")


def views(dist, distance_m):
    ids, pts = PRINTED.layout()
    rng = np.random.default_rng(8)
    out = []
    for T in random_board_poses(PRINTED, 10, seed=7, distance_m=distance_m):
        Xc = pts @ T[:3, :3].T + T[:3, 3]
        uv = cv2.projectPoints(Xc, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
        ok = (uv[:, 0] > 2) & (uv[:, 0] < 638) & (uv[:, 1] > 2) & (uv[:, 1] < 478)
        out.append(Features(ids[ok], uv[ok] + rng.normal(0, 0.1, (int(ok.sum()), 2))))
    return out


def test_a_strong_lens_is_not_a_wrong_board():
    feats = views(np.array([-0.45, 0.2, 0.0, 0.0, 0.0]), (0.22, 0.3))  # board fills the image
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(BoardMismatchError):  # the pinhole alone cannot fit it
            calibrate_board(PRINTED, feats, 640, 480)
    check_geometry(PRINTED, feats, (640, 480))  # OpenCV's lens model does


def test_a_wrong_board_is_refused_naming_the_target_file():
    feats = views(np.array([-0.25, 0.1, 1e-3, -5e-4, 0.0]), (0.35, 0.55))
    check_geometry(PRINTED, feats, (640, 480))
    declared = Charuco((12, 8), 0.02, 0.015, "DICT_5X5_100", "board.toml")
    with pytest.raises(BoardMismatchError, match="board.toml") as err:
        check_geometry(declared, feats, (640, 480))
    assert "inner_corners" in str(err.value.fix)
