"""The board route's predicted tool-point accuracy (selfcal.calibration.board.accuracy, issue #29)
and the model-error split it shares with the tracker route (selfcal.calibration.accuracy)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from selfcal.calibration.accuracy import model_error_of
from selfcal.calibration.board.misfit import pose_jacobian
from selfcal.camera import camera_model
from selfcal.transforms import inv_pose, pose_from_vec, skew


@pytest.mark.parametrize("eye_to_hand", [False, True])
def test_pose_jacobian_against_central_differences(eye_to_hand):
    """The pixels' derivative by a body twist of the tool pose (the camera in the board frame;
    eye-to-hand the board in the camera frame), through a lens with distortion."""
    cam = camera_model("opencv", fx=800.0, mu=1.0, cx=320.0, cy=240.0, width=640, height=480,
                       coeffs={"k1": -0.25, "k2": 0.1, "p1": 1e-3},
                       free=("fx", "mu", "cx", "cy", "k1", "k2"))  # fmt: skip
    T_tool = pose_from_vec(np.r_[0.05, 0.02, -0.4, 3.0, 0.1, 0.2])
    if eye_to_hand:
        T_tool = inv_pose(T_tool)
    X = np.c_[np.random.default_rng(0).uniform(-0.1, 0.1, (20, 2)), np.zeros(20)]

    def pixels(xi: np.ndarray) -> np.ndarray:
        hat = np.zeros((4, 4))
        hat[:3, :3], hat[:3, 3] = skew(xi[3:]), xi[:3]
        T = T_tool @ expm(hat)
        T_cam_board = T if eye_to_hand else inv_pose(T)
        return cam.project(X @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]).reshape(-1)

    T_cam_board = T_tool if eye_to_hand else inv_pose(T_tool)
    x = X @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]
    A = pose_jacobian(cam.project_free(x)[1], x, T_tool, eye_to_hand)
    h = 1e-7
    num = np.stack([(pixels(h * e) - pixels(-h * e)) / (2 * h) for e in np.eye(6)], axis=1)
    assert np.abs(A - num).max() < 1e-6 * np.abs(num).max()


def test_model_error_of_splits_the_held_out_errors():
    """Rows drawn with a known model error on top of a known estimation error and noise: the
    split finds it within 15 % (2000 rows)."""
    rng = np.random.default_rng(4)
    s, nu, m = 0.2, 0.3, 0.5
    e = rng.normal(0.0, np.sqrt(s**2 + nu**2 + m**2), (2000, 3))
    r2 = [np.sum(e**2, axis=1)]
    me = model_error_of(r2, [np.full(2000, 3 * s**2)], [np.full(2000, 3 * nu**2)], None,
                        folds=1, failed=0, noise_what="noise")  # fmt: skip
    assert me is not None and me.rotation_rad is None
    assert me.position_m == pytest.approx(m, rel=0.15)
    assert me.noise_m == pytest.approx(nu) and me.estimation_rms_m == pytest.approx(s * np.sqrt(3))
    # a model error estimated otherwise (the board route's, from the pixels) is taken as given
    given = model_error_of(r2, [np.full(2000, 3 * s**2)], [np.full(2000, 3 * nu**2)], None,
                           folds=1, failed=0, noise_what="noise", given=(0.1, None))  # fmt: skip
    assert (
        given is not None and given.position_m == 0.1 and given.held_out_rms_m == me.held_out_rms_m
    )


def test_the_held_share_is_what_the_folds_excess_shows_of_the_prior():
    """Held-out frames whose squared pixel errors carry 30 % of what the prior's deviation would
    add beyond the estimate's errors and the noise: the share found is 0.3 within 10 % (4000
    frames); none of it shows: 0; more than the prior: capped at 1."""
    from selfcal.calibration.board.held_prior import held_share

    rng = np.random.default_rng(7)
    expected, held = rng.uniform(1.0, 3.0, 4000), rng.uniform(0.0, 2.0, 4000)
    px2 = (expected + 0.3 * held) * rng.chisquare(20, 4000) / 20
    assert held_share(px2, expected, held) == pytest.approx(0.3, rel=0.1)
    assert held_share(0.9 * expected, expected, held) == 0.0
    assert held_share(expected + 2 * held, expected, held) == 1.0
    assert held_share(px2, expected, np.zeros(4000)) == 1.0  # the prior adds nothing
