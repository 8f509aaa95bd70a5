"""Camera calibration from a board of known geometry (selfcal.calibration.board.calibrate)."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from selfcal.calibration.board.calibrate import (
    BoardInputError,
    BoardMismatchError,
    BoardNotFoundWarning,
    calibrate_board,
    opencv_calibration,
)
from selfcal.camera import BrownConrady, Fisheye, Pinhole, opencv_values
from selfcal.sim.lens import LensRemap
from selfcal.target import AprilGrid, Charuco, Chessboard, Features
from selfcal.target.board_views import random_board_poses

CAMERA = Pinhole(800.0, 1.01, 330.0, 235.0, 640, 480, free=("fx", "mu", "cx", "cy"))
NAMES = ("fx", "mu", "cx", "cy")


def analytic_views(board, camera, poses, sigma_px, seed):
    """Features of the board seen at ``poses``: exact projections + Gaussian noise, in-image
    only."""
    rng = np.random.default_rng(seed)
    ids, pts = board.layout()
    out = []
    for T in poses:
        uv = camera.project(pts @ T[:3, :3].T + T[:3, 3])
        ok = camera.in_image(uv, 2.0)
        out.append(Features(ids[ok], uv[ok] + rng.normal(0, sigma_px, (int(ok.sum()), 2))))
    return out


def image_views(board, camera, poses, blur_px=0.7):
    """Images of the printed board seen by ``camera`` at ``poses`` (pinhole: the board image
    warped by the plane's homography), blurred like optics."""
    bi = board.image(px_per_mm=6.0)
    x0, y0 = bi.extent_m[:2]
    s = 1.0 / bi.px_per_m
    A = np.array([[s, 0, x0 + 0.5 * s], [0, s, y0 + 0.5 * s], [0, 0, 1.0]])  # px -> board m
    out = []
    for T in poses:
        H = camera.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
        img = cv2.warpPerspective(
            bi.pixels, H, (camera.width, camera.height), flags=cv2.INTER_AREA, borderValue=128
        )
        out.append(cv2.GaussianBlur(img, (0, 0), blur_px))
    return out


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BoardNotFoundWarning)
        return fn(*a, **kw)


def test_analytic_views_give_the_camera_within_its_uncertainty():
    board = Charuco((11, 8), 0.02, 0.015)
    poses = random_board_poses(board, 12, seed=1)
    res = calibrate_board(board, analytic_views(board, CAMERA, poses, 0.1, seed=2), 640, 480)
    for n in NAMES:
        assert abs(getattr(res.camera, n) - getattr(CAMERA, n)) < 3 * res.std[n], n
    # the fitted noise is the simulated one (0.1 px per coordinate; measured 0.1006)
    assert res.sigma_px == pytest.approx(0.1, rel=0.1)
    T = np.stack(poses)
    np.testing.assert_allclose(res.T_cam_board[:, :3, 3], T[:, :3, 3], atol=2e-3)


def test_board_images_against_opencv():
    """The same board images through OpenCV: intrinsics within 2 sigma of
    cv2.calibrateCamera's and a reprojection RMS no higher."""
    board = Charuco((11, 8), 0.02, 0.015)
    poses = random_board_poses(board, 10, seed=3)
    feats = [board.detect(img) for img in image_views(board, CAMERA, poses)]
    res = _quiet(calibrate_board, board, feats, 640, 480)
    cv = res.opencv
    for n in ("fx", "cx", "cy"):
        assert abs(getattr(res.camera, n) - getattr(cv.camera, n)) < 2 * cv.std[n], n
    assert abs(res.camera.fy - cv.camera.fy) < 2 * cv.std["fy"]
    assert res.rms_all_px <= cv.rms_px * (1 + 1e-6)
    # and the truth within 3 sigma (detection errors of the rendered corners, not noise)
    for n in NAMES:
        assert abs(getattr(res.camera, n) - getattr(CAMERA, n)) < 3 * res.std[n], n


def test_images_without_the_board_are_named_counted_and_skipped():
    board = Chessboard((9, 6), 0.025)
    poses = random_board_poses(board, 6, seed=4)
    feats = analytic_views(board, CAMERA, poses, 0.1, seed=5)
    feats[2] = Features(np.zeros(0, np.int64), np.zeros((0, 2)))
    feats[4] = Features(np.zeros(0, np.int64), np.zeros((0, 2)))
    names = [f"{i:04d}_cam0" for i in range(6)]
    with pytest.warns(BoardNotFoundWarning, match=r"2 of 6 image.*0002_cam0, 0004_cam0"):
        res = calibrate_board(board, feats, 640, 480, names=names)
    assert res.skipped == ("0002_cam0", "0004_cam0")
    assert not res.used[2] and np.isnan(res.T_cam_board[2]).all()
    with pytest.raises(BoardInputError, match="only 2 of 3 image"):
        _quiet(calibrate_board, board, feats[:3], 640, 480, names=names[:3])


def test_a_chessboard_declared_with_the_wrong_corner_count_is_not_found():
    printed = Chessboard((9, 6), 0.025)
    declared = Chessboard((7, 6), 0.025, source="board.toml")
    imgs = image_views(printed, CAMERA, random_board_poses(printed, 4, seed=6))
    feats = [declared.detect(img) for img in imgs]
    with pytest.raises(BoardInputError, match="board.toml") as info:
        _quiet(calibrate_board, declared, feats, 640, 480)
    assert "inner_corners" in str(info.value.fix)


def test_detections_that_do_not_fit_the_declared_geometry_are_refused():
    printed = Charuco((11, 8), 0.02, 0.015)
    poses = random_board_poses(printed, 8, seed=7)
    feats = analytic_views(printed, CAMERA, poses, 0.1, seed=8)
    # declared with 12 x 8 inner corners: the same corner ids sit elsewhere on the board
    declared = Charuco((12, 8), 0.02, 0.015, source="board.toml")
    with pytest.raises(BoardMismatchError, match="reprojection RMS") as info:
        calibrate_board(declared, feats, 640, 480)
    assert "inner_corners" in str(info.value.fix) and "board.toml" in str(info.value.fix)
    # declared with 9 x 8: ids the declared board does not have
    with pytest.raises(BoardMismatchError, match="not on the declared board"):
        calibrate_board(Charuco((9, 8), 0.02, 0.015), feats, 640, 480)


LENS_FREE = (*NAMES, "k1", "k2", "p1", "p2")
LENS = BrownConrady.from_pinhole(CAMERA, (-0.2, 0.08, 5e-4, -3e-4, 0, 0, 0, 0), LENS_FREE)


def lens_image_views(board, camera, poses, blur_px=0.7):
    """:func:`image_views` through ``camera``'s lens: the board drawn into the renderer's source
    pinhole (:func:`selfcal.sim.lens.source_pinhole`), then remapped exactly (:class:`selfcal.sim.lens.LensRemap`)."""
    remap = LensRemap(camera)
    return [remap(img) for img in image_views(board, remap.source, poses, blur_px)]


def test_analytic_views_give_the_lens_within_its_uncertainty():
    board = Charuco((11, 8), 0.02, 0.015)
    poses = random_board_poses(board, 12, seed=1)
    feats = analytic_views(board, LENS, poses, 0.1, seed=2)
    res = calibrate_board(board, feats, 640, 480, model="opencv", free=LENS_FREE)
    assert res.camera.model_name == "opencv" and res.camera.free == LENS_FREE
    truth = dict(zip(LENS.names, LENS.values(), strict=True))
    got = dict(zip(LENS.names, res.camera.values(), strict=True))
    for n in LENS_FREE:  # measured |error| / sigma <= 2.2 (p1)
        assert abs(got[n] - truth[n]) < 3 * res.std[n], n
    assert res.camera.coefficient("k3") == 0.0  # held: not asked for
    # the pinhole on the same views is clearly worse (the lens is what it cannot fit)
    pin = calibrate_board(board, feats, 640, 480, mismatch_px=50.0)
    assert pin.rms_all_px > 2 * res.rms_all_px  # measured 0.47 vs 0.14 px
    assert abs(pin.camera.fx - CAMERA.fx) > 5 * pin.std["fx"]  # measured 13 sigma off


def test_lens_board_images_against_opencv():
    """Images rendered through the lens, the same features through OpenCV: intrinsics and
    distortion within 2 sigma of cv2.calibrateCamera's and a reprojection RMS no higher
    (measured 0.2438 px both)."""
    board = Charuco((11, 8), 0.02, 0.015)
    poses = random_board_poses(board, 10, seed=3)
    feats = [board.detect(img) for img in lens_image_views(board, LENS, poses)]
    res = _quiet(calibrate_board, board, feats, 640, 480, model="opencv", free=LENS_FREE)
    cv = res.opencv
    ours = opencv_values(res.camera)
    theirs = opencv_values(cv.camera)
    for n in (
        "fx",
        "fy",
        "cx",
        "cy",
        "k1",
        "k2",
        "p1",
        "p2",
    ):  # measured |diff| / std < 1e-6: the same minimum
        assert abs(ours[n] - theirs[n]) < 2 * cv.std[n], n
    assert res.rms_all_px <= cv.rms_px * (1 + 1e-6)
    truth = dict(zip(LENS.names, LENS.values(), strict=True))
    got = dict(zip(LENS.names, res.camera.values(), strict=True))
    for n in LENS_FREE:  # and the truth within 3 sigma (measured <= 1.2)
        assert abs(got[n] - truth[n]) < 3 * res.std[n], n


def test_fisheye_from_analytic_views():
    board = Charuco((11, 8), 0.02, 0.015)
    true = Fisheye.from_pinhole(CAMERA, (0.05, -0.02, 0.01, 0.0))
    poses = random_board_poses(board, 12, seed=1)
    free = (*NAMES, "k1", "k2", "k3", "k4")
    res = calibrate_board(board, analytic_views(board, true, poses, 0.1, seed=2), 640, 480,
                          model="fisheye", free=free)  # fmt: skip
    got = dict(zip(true.names, res.camera.values(), strict=True))
    want = dict(zip(true.names, true.values(), strict=True))
    assert got["skew"] == 0.0  # held (cv2.fisheye's CALIB_FIX_SKEW, then the adjustment)
    for n in free:  # measured |error| / sigma <= 1.8
        assert abs(got[n] - want[n]) < 3 * res.std[n], n


def test_a_free_skew_is_estimated_and_exported_as_k01():
    """``skew`` (K[0, 1], px) is a free parameter when named: OpenCV's calibration starts it
    at 0 and the bundle adjustment frees it. A camera with skew 1.5 px: every parameter within
    3 sigma (measured |z| <= 2.1, skew std 0.105 px, 14 sigma from zero). The exports carry it
    as K[0, 1] and calibration.json's camera entry names it."""
    import json

    from selfcal.export.camera import to_camera_info_yaml, to_opencv_yaml
    from selfcal.io.board_calibration import camera_json

    free = (*NAMES, "skew")
    true = Pinhole(800.0, 1.01, 330.0, 235.0, 640, 480, free=free, skew=1.5)
    board = Charuco((11, 8), 0.02, 0.015)
    views = analytic_views(board, true, random_board_poses(board, 12, seed=1), 0.1, seed=2)
    res = calibrate_board(board, views, 640, 480, free=free)
    assert res.camera.free == free
    z = {n: (getattr(res.camera, n) - getattr(true, n)) / res.std[n] for n in free}
    print("skew z:", {k: round(v, 2) for k, v in z.items()}, "std", res.std["skew"])
    assert all(abs(v) < 3 for v in z.values()), z
    assert abs(res.camera.skew) > 5 * res.std["skew"]  # found: 14 sigma from zero
    mode = cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY
    fs = cv2.FileStorage(to_opencv_yaml(res.camera), mode)
    assert fs.getNode("camera_matrix").mat()[0, 1] == pytest.approx(res.camera.skew, abs=1e-12)
    assert f"data: [{res.camera.fx!r}, {res.camera.skew!r}," in to_camera_info_yaml(res.camera)
    doc = json.loads(json.dumps(camera_json("cam0", res.camera, res.std)))
    assert doc["parameters"]["skew"] == res.camera.skew == opencv_values(res.camera)["skew"]


def test_a_free_skew_of_the_fisheye_starts_from_opencvs_alpha():
    """The fisheye frees OpenCV's alpha (= skew / fx) when ``skew`` is free, and the adjustment
    refines it: every parameter within 3 sigma (measured |z| <= 1.5)."""
    board = Charuco((11, 8), 0.02, 0.015)
    free = (*NAMES, "skew", "k1", "k2")
    true = Fisheye.from_pinhole(
        Pinhole(800.0, 1.01, 330.0, 235.0, 640, 480, skew=1.5), (0.05, -0.02, 0.0, 0.0), free
    )
    views = analytic_views(board, true, random_board_poses(board, 12, seed=1), 0.1, seed=2)
    res = calibrate_board(board, views, 640, 480, model="fisheye", free=free)
    got = dict(zip(true.names, res.camera.values(), strict=True))
    want = dict(zip(true.names, true.values(), strict=True))
    z = {n: (got[n] - want[n]) / res.std[n] for n in free}
    print("fisheye skew z:", {k: round(v, 2) for k, v in z.items()})
    assert all(abs(v) < 3 for v in z.values()), z


def test_a_wide_fisheye_starts_from_its_field_of_view():
    """AprilGrid views of a 1279x1023 fisheye (fx 512 px, true k1..k4 0.021, -0.011, 0.003,
    -0.0008; tests/data/fisheye_aprilgrid_views.npz, detected in a stranger's rendered images):
    the homographies' pinhole start is fx 3325 px, from where cv2.fisheye.calibrate failed an
    assertion (InitExtrinsics); the field-of-view starts reach the truth."""
    with np.load(Path(__file__).parents[1] / "data" / "fisheye_aprilgrid_views.npz") as data:
        cuts = np.cumsum(data["counts"])[:-1]
        views = [Features(i.astype(np.int64), u.astype(float))
                 for i, u in zip(np.split(data["ids"], cuts), np.split(data["uv"], cuts))]  # fmt: skip
    board = AprilGrid((6, 6), 0.04, 0.3)
    free = ("fx", "mu", "cx", "cy", "k1", "k2", "k3", "k4")
    res = opencv_calibration(board, views, 1279, 1023, free, "fisheye")
    assert res.camera.fx == pytest.approx(512.0, rel=5e-3)  # measured 511.2
    assert res.rms_px < 0.2  # measured 0.07
