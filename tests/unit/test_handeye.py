"""Hand-eye calibration from flange poses (selfcal.calibration.handeye.calibrate): a board projected through known
poses, eye-in-hand and eye-to-hand; noise-free exact, with noise within 3 sigma; the linear
start refuses motions about one axis; the pose chain's Jacobian is the residuals' derivative."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.handeye import camera_refinement
from selfcal.calibration.handeye.calibrate import calibrate_hand_eye, chain_motions
from selfcal.calibration.handeye.calibration_file import camera_section
from selfcal.calibration.handeye.eiv import EXACT
from selfcal.calibration.handeye.fit import CV_MARGIN, predict_better
from selfcal.calibration.handeye.linear import HandEyeStartError, linear_hand_eye
from selfcal.camera import camera_model
from selfcal.errors import UsageError
from selfcal.estimation.pose_chain import PoseChainBlock
from selfcal.target.base import Features
from selfcal.target.boards import Chessboard
from selfcal.transforms import inv_pose, make_pose

BOARD = Chessboard((7, 5), 0.03)
CAMERA = camera_model("opencv", fx=900.0, mu=1.002, cx=645.0, cy=478.0, width=1280, height=960,
                      coeffs={"k1": -0.12, "k2": 0.08}, free=("fx", "mu", "cx", "cy", "k1", "k2"))  # fmt: skip
CENTRE = BOARD.points(np.arange(35)).mean(axis=0)


def _look_at(eye: np.ndarray, target: np.ndarray, rng) -> np.ndarray:
    """T_world_cam of a camera at ``eye`` looking at ``target`` with a random roll."""
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, rng.normal(size=3))
    x /= np.linalg.norm(x)
    return make_pose(np.stack([x, np.cross(z, x), z], axis=1), eye)


def _scene(setup: str, n: int, seed: int):
    """Truth X, B and flange poses whose views see the whole board from 0.4-0.6 m."""
    rng = np.random.default_rng(seed)
    X = make_pose(Rotation.random(random_state=seed).as_matrix(), rng.uniform(-0.1, 0.1, 3))
    B = make_pose(Rotation.random(random_state=seed + 1).as_matrix(), rng.uniform(-0.2, 0.2, 3))
    if setup == "eye-to-hand":
        X[:3, 3] += [0.0, 1.0, 0.5]  # the static camera in the base frame
    else:
        B[:3, 3] += [0.6, 0.0, 0.0]  # the static board in the base frame
    flange = []
    for _ in range(n):  # a camera pose around the board's normal, then the flange that gives it
        d = rng.uniform(0.4, 0.6)
        eye_b = CENTRE + d * np.r_[rng.uniform(-0.5, 0.5, 2), -1.0] / np.sqrt(1.25)
        T_board_cam = _look_at(eye_b, CENTRE, rng)
        T_cam_board = inv_pose(T_board_cam)
        # T_cam_board = X^-1 A B  ->  A = X T_cam_board B^-1
        A = X @ T_cam_board @ inv_pose(B)
        flange.append(A if setup == "eye-to-hand" else inv_pose(A))
    return X, B, np.array(flange)


def _features(X, B, A, noise_px: float, seed: int) -> list[Features]:
    rng = np.random.default_rng(seed)
    ids = np.arange(35)
    P = BOARD.points(ids)
    out = []
    for Ai in A:
        T = inv_pose(X) @ Ai @ B
        uv = CAMERA.project(P @ T[:3, :3].T + T[:3, 3])
        out.append(Features(ids, uv + rng.normal(0.0, noise_px, uv.shape)))
    return out


def _rot_deg(R1, R2):
    return np.degrees(np.linalg.norm(Rotation.from_matrix(R1 @ R2.T).as_rotvec()))


# each setup with one of the camera's treatments (the cross-validated choice between them:
# test_the_camera_choice_is_recorded_and_obeyed)
SETUP_CAMERA = [("eye-in-hand", "refined"), ("eye-to-hand", "held")]


@pytest.mark.parametrize(("setup", "camera"), SETUP_CAMERA)
def test_noise_free_is_exact(setup, camera):
    X, B, F = _scene(setup, 12, seed=5)
    feats = _features(X, B, chain_motions(setup, F), 0.0, 1)
    cal = calibrate_hand_eye(BOARD, feats, F, setup, 1280, 960, model="opencv", free=CAMERA.free,
                             camera=camera)  # fmt: skip
    c = cal.calibrated
    assert np.abs(c.X[:3, 3] - X[:3, 3]).max() < 1e-6
    assert np.abs(c.B[:3, 3] - B[:3, 3]).max() < 1e-6
    assert _rot_deg(c.X[:3, :3], X[:3, :3]) < 1e-6 and _rot_deg(c.B[:3, :3], B[:3, :3]) < 1e-6
    np.testing.assert_allclose(c.camera.values(), CAMERA.values(), rtol=0, atol=1e-6)


@pytest.mark.parametrize(("setup", "camera"), [(s, "held" if c == "refined" else "refined")
                                               for s, c in SETUP_CAMERA])  # fmt: skip
def test_noisy_within_three_sigma(setup, camera):
    X, B, F = _scene(setup, 15, seed=7)
    feats = _features(X, B, chain_motions(setup, F), 0.3, 2)
    cal = calibrate_hand_eye(BOARD, feats, F, setup, 1280, 960, model="opencv", free=CAMERA.free,
                             camera=camera)  # fmt: skip
    c = cal.calibrated
    for T, truth, std in ((c.X, X, c.X_std), (c.B, B, c.B_std)):
        assert np.all(np.abs(T[:3, 3] - truth[:3, 3]) < 3 * std[3:])
        w = Rotation.from_matrix(truth[:3, :3] @ T[:3, :3].T).as_rotvec()  # truth = Rot(w) T
        assert np.all(np.abs(w) < 3 * std[:3])
    assert 0.25 < c.sigma_px < 0.35  # the noise per coordinate is recovered
    assert c.rms_px <= cal.nominal.rms_px + 1e-9  # the camera freed never fits worse


def test_linear_start_refuses_motions_about_one_axis():
    A = make_pose(Rotation.from_rotvec(np.outer(np.linspace(0.1, 1, 6), [0, 0, 1])).as_matrix(),
                  np.random.default_rng(1).normal(size=(6, 3)))  # fmt: skip
    with pytest.raises(HandEyeStartError, match="one axis"):
        linear_hand_eye(A, A)


def test_pose_chain_jacobian_matches_finite_differences():
    X, B, F = _scene("eye-to-hand", 4, seed=3)
    A = chain_motions("eye-to-hand", F)
    view = np.repeat(np.arange(4), 35)
    pts = np.tile(BOARD.points(np.arange(35)), (4, 1))
    blk = PoseChainBlock(CAMERA, A, X, B, view, pts, np.zeros((len(view), 2)))
    rng = np.random.default_rng(0)
    vals = {"intrinsics": CAMERA.free_values(), "X": rng.normal(0, 0.01, 6),
            "B": rng.normal(0, 0.01, 6)}  # fmt: skip
    ev = blk.evaluate(vals, True)
    for piece in ev.pieces:
        v0 = vals[piece.block]
        for j in range(v0.size):
            h = 1e-7 * max(1.0, abs(v0[j]))
            up = dict(vals, **{piece.block: v0 + h * np.eye(v0.size)[j]})
            dn = dict(vals, **{piece.block: v0 - h * np.eye(v0.size)[j]})
            fd = (blk.evaluate(up, False).residuals - blk.evaluate(dn, False).residuals) / (2 * h)
            np.testing.assert_allclose(piece.J[:, :, j], fd, rtol=1e-5, atol=1e-4)


def _convention_csv(path, convention: str, T) -> None:
    """Flange poses ``T`` written as a controller of ``convention`` prints them."""
    rot = Rotation.from_matrix(T[:, :3, :3])
    cols, vals = {
        "quaternion-xyzw": (["qx", "qy", "qz", "qw"], rot.as_quat()),
        "abb-quaternion": (["q1", "q2", "q3", "q4"], rot.as_quat()[:, [3, 0, 1, 2]]),
        "kuka-abc": (["a", "b", "c"], rot.as_euler("ZYX", degrees=True)),
        "fanuc-wpr": (["w", "p", "r"], rot.as_euler("xyz", degrees=True)),
        "ur-rotvec": (["rx", "ry", "rz"], rot.as_rotvec()),
    }[convention]
    rows = np.hstack([T[:, :3, 3] * 1000.0, vals])
    path.write_text(",".join(["x_mm", "y_mm", "z_mm", *cols]) + "\n"
                    + "".join(",".join(f"{v:.17g}" for v in r) + "\n" for r in rows))  # fmt: skip


@pytest.fixture(scope="module")
def convention_case():
    """The flange poses, their features and the hand-eye calibration from the poses as arrays
    (the reference of every convention below: one calibration, not one per convention)."""
    X, B, F = _scene("eye-to-hand", 10, seed=11)
    feats = _features(X, B, chain_motions("eye-to-hand", F), 0.2, 3)
    ref = calibrate_hand_eye(BOARD, feats, F, "eye-to-hand", 1280, 960, free=CAMERA.free,
                             pose_noise=EXACT, camera="refined").calibrated  # fmt: skip
    return F, feats, ref


@pytest.mark.parametrize(
    "convention", ["quaternion-xyzw", "abb-quaternion", "kuka-abc", "fanuc-wpr", "ur-rotvec"]
)
def test_each_rotation_convention_gives_the_same_hand_eye(tmp_path, convention, convention_case):
    from selfcal.io.poses.files import read_poses

    F, feats, ref = convention_case
    _convention_csv(tmp_path / "poses.csv", convention, F)
    rows = read_poses(tmp_path / "poses.csv", "ur-rotvec" if convention == "ur-rotvec" else None)
    assert rows.convention == convention
    got = calibrate_hand_eye(BOARD, feats, rows.T_base_flange, "eye-to-hand", 1280, 960,
                             free=CAMERA.free, pose_noise=EXACT, camera="refined").calibrated  # fmt: skip
    np.testing.assert_allclose(got.X, ref.X, atol=1e-9)
    np.testing.assert_allclose(got.B, ref.B, atol=1e-9)
    assert abs(got.rms_px - ref.rms_px) < 1e-9


def test_the_wrong_setup_is_named_by_the_other_setups_fit():
    from selfcal.calibration.handeye.calibrate import HandEyeMisfitError

    X, B, F = _scene("eye-to-hand", 10, seed=13)
    feats = _features(X, B, chain_motions("eye-to-hand", F), 0.2, 4)
    with pytest.raises(HandEyeMisfitError, match="as eye-to-hand they fit") as exc:
        calibrate_hand_eye(BOARD, feats, F, "eye-in-hand", 1280, 960, free=CAMERA.free)
    assert "--setup eye-to-hand" in exc.value.fix


def test_rows_paired_with_the_wrong_images_are_named_by_the_turn_angles():
    from selfcal.calibration.handeye.calibrate import HandEyeMisfitError

    X, B, F = _scene("eye-in-hand", 10, seed=17)
    feats = _features(X, B, chain_motions("eye-in-hand", F), 0.2, 5)
    shifted = np.roll(F, 1, axis=0)  # every pose row one image off
    with pytest.raises(HandEyeMisfitError, match="turn by angles that differ"):
        calibrate_hand_eye(BOARD, feats, shifted, "eye-in-hand", 1280, 960, free=CAMERA.free)


def _handeye_file(tmp_path, edit=None):
    """A hand-eye calibration.json written by handeye_document (fits of a pinhole camera)."""
    from types import SimpleNamespace

    from selfcal.calibration.handeye.calibrate import FRAMES, HandEyeFit
    from selfcal.calibration.handeye.calibration_file import handeye_document
    from selfcal.camera import Pinhole

    fit = HandEyeFit(Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480), {}, np.eye(4), np.eye(4),
                     np.zeros(6), np.zeros(6), 0.1, np.ones(4, bool), 0.1, 3)  # fmt: skip
    cal = SimpleNamespace(setup=next(iter(FRAMES)), camera_stage=SimpleNamespace(rms_px=0.1),
                          nominal=fit, calibrated=fit, used=np.ones(4, bool),
                          pose_choice=None, camera_refined=True, camera_choice=None)  # fmt: skip
    doc = handeye_document(cal, "ds")
    if edit is not None:
        edit(doc)
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(doc))
    return path


def _scale(T):
    return (np.array(T) * 2).tolist()


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda d: d["camera"]["values"].update(fx=float("nan")), "camera.values.fx"),
        (lambda d: d["camera"]["values"].update(fx=-800.0), "camera.values.fx"),
        (lambda d: d["hand_eye"].update(matrix=_scale(d["hand_eye"]["matrix"])), "hand_eye.matrix"),
        (lambda d: d["nominal"]["board_mount"].update(matrix=[[float("nan")] * 4] * 4),
         "nominal.board_mount.matrix"),
        (lambda d: d["camera"].pop("free"), "camera.free"),
    ],
)  # fmt: skip
def test_a_damaged_handeye_calibration_is_refused_naming_the_key(tmp_path, edit, key):
    """#33: every calibration.json reader checks what it reads (before: NaN and a negative focal
    length were read back, a missing key was named as KeyError's text)."""
    from selfcal.calibration.handeye.calibration_file import read_handeye
    from selfcal.errors import InputError

    read_handeye(_handeye_file(tmp_path))  # the undamaged file reads
    with pytest.raises(InputError, match=rf"calibration.json: (missing )?key '{re.escape(key)}'"):
        read_handeye(_handeye_file(tmp_path, edit))


def test_the_camera_choice_is_recorded_and_obeyed():
    X, B, F = _scene("eye-to-hand", 12, seed=11)
    feats = _features(X, B, chain_motions("eye-to-hand", F), 0.3, 3)
    run = lambda camera: calibrate_hand_eye(BOARD, feats, F, "eye-to-hand", 1280, 960,  # noqa: E731
                                            free=CAMERA.free, pose_noise=EXACT, camera=camera)  # fmt: skip
    auto, held = run("auto"), run("held")
    ch = auto.camera_choice
    assert ch is not None and ch.folds == 8 and len(ch.held_fold_px) == len(ch.refined_fold_px) == 8
    assert ch.refined == (ch.held_px > (1 + CV_MARGIN) * ch.refined_px)
    assert (auto.calibrated is auto.nominal) == (not ch.refined)
    assert auto.camera_refined == ch.refined
    # left-out corners predicted at about the corner noise (0.3 px per coordinate: 0.42 px)
    assert 0.35 < min(ch.held_px, ch.refined_px) < 0.6
    assert held.calibrated is held.nominal and not held.camera_refined
    assert held.camera_choice is None
    # calibration.json says who chose: the cross-validation, or the caller (--camera)
    sec = camera_section(auto)
    assert sec["chosen_by"] == "cross-validation" and sec["cross_validation"]["folds"] == 8
    assert sec["treatment"] == ("refined" if ch.refined else "held")
    assert camera_section(held) == {"treatment": "held", "chosen_by": "caller",
                                    "cross_validation": None}  # fmt: skip
    with pytest.raises(UsageError):
        run("free")


def test_a_held_camera_that_fails_in_a_fold_is_no_vote_for_refining(monkeypatch):
    """A fold whose held camera cannot be calibrated (fold_camera raises) is left out of both
    RMS, not counted as an infinite error that would choose the refined camera; with none left
    the camera is held; calibration.json and the line for people say how many failed."""
    from selfcal.calibration.handeye.calibration_file import camera_text
    from selfcal.errors import EstimationError

    X, B, F = _scene("eye-to-hand", 12, seed=11)
    feats = _features(X, B, chain_motions("eye-to-hand", F), 0.3, 3)
    real, calls = camera_refinement.fold_camera, []

    def flaky(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1 or fail_all:
            raise EstimationError("the fold's board calibration did not converge (test)")
        return real(*args, **kwargs)

    monkeypatch.setattr(camera_refinement, "fold_camera", flaky)
    run = lambda: calibrate_hand_eye(BOARD, feats, F, "eye-to-hand", 1280, 960,  # noqa: E731
                                     free=CAMERA.free, pose_noise=EXACT, camera="auto")  # fmt: skip
    fail_all = False
    ch = run().camera_choice
    assert ch is not None and ch.held_failed == 1 and not np.isfinite(ch.held_fold_px[0])
    # pooled over the 7 folds both predicted: finite, and within their folds' range
    assert min(ch.held_fold_px[1:]) <= ch.held_px <= max(ch.held_fold_px[1:])
    assert min(ch.refined_fold_px[1:]) <= ch.refined_px <= max(ch.refined_fold_px[1:])
    assert ch.refined == predict_better(ch.refined_px, ch.held_px)
    fail_all, calls[:] = True, []
    cal = run()
    assert cal.camera_choice.held_failed == 8 and not cal.camera_choice.refined
    assert not cal.camera_refined
    sec = camera_section(cal)
    assert sec["cross_validation"]["held_failed_folds"] == 8
    assert "could not be calibrated in 8 of 8 folds" in camera_text(sec)


def test_one_rule_chooses_the_flange_poses_and_the_camera():
    # the default model gives way only to one better by more than CV_MARGIN (1 %)
    assert CV_MARGIN == 0.01
    assert not predict_better(1.0, 1.0099) and predict_better(1.0, 1.0101)
    assert not predict_better(1.0, 1.0) and not predict_better(float("inf"), 1.0)
    assert predict_better(1.0, float("inf"))
    assert camera_refinement.predict_better is predict_better


@pytest.mark.slow
def test_the_held_cameras_own_error_is_in_the_sigmas():
    # the answer holding the camera stage's camera: its sigmas carry that camera's covariance
    # (measured: RMS z 0.88-1.09; without it 4.2 and 11.9 for X's rotation and translation)
    z = []
    for seed in range(12):
        X, B, F = _scene("eye-to-hand", 15, seed=100 + seed)
        feats = _features(X, B, chain_motions("eye-to-hand", F), 0.3, 1000 + seed)
        c = calibrate_hand_eye(BOARD, feats, F, "eye-to-hand", 1280, 960, free=CAMERA.free,
                               pose_noise=EXACT, camera="held").calibrated  # fmt: skip
        for T, truth, std in ((c.X, X, c.X_std), (c.B, B, c.B_std)):
            w = Rotation.from_matrix(truth[:3, :3] @ T[:3, :3].T).as_rotvec()
            z.append(np.r_[w / std[:3], (T[:3, 3] - truth[:3, 3]) / std[3:]])
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((0.6 < rms) & (rms < 1.5)), rms


def test_a_folds_camera_is_the_board_calibration_of_its_images_alone():
    from selfcal.calibration.board.calibrate import calibrate_board

    X, B, F = _scene("eye-in-hand", 12, seed=19)
    feats = _features(X, B, chain_motions("eye-in-hand", F), 0.3, 5)
    stage = calibrate_board(BOARD, feats, 1280, 960, free=CAMERA.free, model="opencv")
    uv = np.concatenate([f.uv for f in feats])
    images = np.flatnonzero(np.arange(12) % 4 != 1)  # one of 4 folds out: 9 images
    got = camera_refinement.fold_camera(stage, BOARD, uv, images)
    ref = calibrate_board(BOARD, [feats[i] for i in images], 1280, 960, free=CAMERA.free,
                          model="opencv")  # fmt: skip
    # from the full data's camera, without OpenCV's start or a robust pass: the same minimum,
    # to the solvers' tolerance (measured: 1.2e-6 sigma), where the full data's camera is not
    # (0.92 sigma)
    sigma = np.array([ref.std[k] for k in ref.camera.free])
    z = np.abs(got.free_values() - ref.camera.free_values()) / sigma
    assert z.max() < 4e-6, z
    assert np.max(np.abs(stage.camera.free_values() - ref.camera.free_values()) / sigma) > 0.3
