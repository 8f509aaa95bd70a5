"""The board route's predicted tool-point accuracy (selfcal.calibration.board.accuracy, issue #29)
and the model-error split it shares with the tracker route (selfcal.calibration.accuracy)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.linalg import expm

from selfcal.calibration.accuracy import model_error_of, spans_json
from selfcal.calibration.board.accuracy import board_error_model_from_json, grown_size
from selfcal.calibration.board.misfit import pose_jacobian
from selfcal.camera import camera_model
from selfcal.errors import InputError
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc, param_names
from selfcal.kinematics.tool_error import joint_spans, revolute_joints
from selfcal.robot.definition import load_robot
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
    # the held deviation's share at the held-out rows (the board route's) is written when
    # measured, in mm and deg, and left out where not (the tracker route)
    assert "held_deviation_rms_mm" not in me.to_json()
    held = dataclasses.replace(me, held_rms_m=2.5e-3, held_rms_rad=np.radians(0.25)).to_json()
    assert held["held_deviation_rms_mm"] == pytest.approx(2.5)
    assert held["held_deviation_rms_deg"] == pytest.approx(0.25)


def test_the_held_share_is_what_the_folds_excess_shows_of_the_prior():
    """Folds whose pixel excess carries 30 % of what the prior's deviation would add to them,
    with noise: the point estimate is 0.3 within 10 % on 400 folds, and the share counted is its
    upper bound, above it by less than 10 %; more than the prior: counted 1; nothing held, one
    fold: the prior unscaled, said so."""
    from selfcal.calibration.board.held_prior import held_share

    rng = np.random.default_rng(7)
    added = rng.uniform(1.0, 3.0, 400)
    excess = 0.3 * added + rng.normal(0.0, 0.3 * np.sqrt(added))
    s = held_share(excess, added, np.full(400, 10.0))
    assert s.basis == "folds" and s.folds == 400
    assert s.estimate == pytest.approx(0.3, rel=0.1)
    assert s.upper is not None and s.estimate < s.upper < 1.1 * s.estimate and s.used == s.upper
    assert held_share(2 * added, added, np.full(400, 10.0)).used == 1.0
    nothing = held_share(excess, np.full(400, 1e-14), np.full(400, 10.0))
    assert (nothing.basis, nothing.used) == ("nothing_held", 1.0)
    one = held_share(excess[:1], added[:1], np.full(1, 10.0))
    assert (one.basis, one.used, one.estimate) == ("no_folds", 1.0, None)


def test_a_held_deviation_too_small_for_the_folds_is_counted_unscaled_and_said_so():
    """Held directions a chain cannot tell from the others (a 7-joint arm's betas) add only
    rounding to the folds' pixels (2.5e-6 px^2 against a 0.23 px^2 standard deviation of the
    summed excess): the share is not measured (it was: the point estimate -2.05e+07, which
    report.md printed), the prior is counted unscaled, and the sentence says why, with no share
    figure; the same folds with a measurable deviation are measured as before."""
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.held_prior import held_block, held_sentence, held_share

    excess = np.array([-0.02, 0.01, -0.03, -0.01, 0.0])
    added = np.full(5, 5e-7)
    var = np.full(5, 0.0106)
    s = held_share(excess, added, np.full(5, 1.5), var)
    assert (s.basis, s.used, s.estimate, s.upper) == ("unmeasurable", 1.0, None, None)
    words = held_sentence(held_block(Deviation(), s))
    assert words is not None and "counted unscaled" in words and "too little" in words
    assert "e+0" not in words
    before = held_share(excess, added, np.full(5, 1.5))  # without the variance: as before
    assert before.basis == "folds" and before.estimate is not None and before.estimate < -1e4
    measured = held_share(excess + 0.3 * 0.2, np.full(5, 0.2), np.full(5, 1.5), var)
    assert measured.basis == "folds" and measured.estimate == pytest.approx(
        0.3 - 0.05
    )  # sums: (0.3 - 0.05) / 1.0


def test_the_report_sets_the_rms_beside_the_largest_bound_and_the_spread():
    """report.md's accuracy section: the line's figures are the largest 95 % bounds, the
    predicted RMS beside them; the jackknife spread's RMS beside the predicted RMS, and past
    1.5x the words on the jackknife's upward bias with few configurations (a 7-joint arm's
    12 configurations: 0.240 against 0.098 mm)."""
    from selfcal.pipeline.board_accuracy import rms_words, spread_against_prediction

    regions = {"inside": {"position_rms_mm": 0.098}, "calibration_postures":
               {"position_rms_mm": 0.092}}  # fmt: skip
    assert (
        "predicted RMS error is 0.098 mm inside the calibrated region, 0.092 mm at the "
        "calibration postures" in rms_words(regions)
    )
    assert rms_words({}) == ""
    far = {"resamplings": 5, "regions": {"inside": {"spread_mm_rms": 0.240}}}
    text = spread_against_prediction(far, regions, {"configurations": 12})
    assert "0.240 mm, 2.45x the predicted RMS error there (0.098 mm)" in text
    assert "biased upward" in text and "12 configurations in 5 folds" in text
    near = {"resamplings": 5, "regions": {"inside": {"spread_mm_rms": 0.120}}}
    assert spread_against_prediction(near, regions, None).endswith("(0.098 mm).")
    assert spread_against_prediction({"regions": {}}, regions, None) == ""


def test_the_held_shares_upper_bound_covers_the_true_share_on_few_folds():
    """3 folds, each's excess the true share 0.3 of what the prior adds plus noise, 2000 times:
    the upper bound lies above 0.3 in 92-98 % of them (a 95 % bound), and the share counted
    falls to 0 in fewer than 1.5 % where the point estimate does in more than 5 % (7.4 %)."""
    from selfcal.calibration.board.held_prior import held_share

    rng = np.random.default_rng(3)
    added = rng.uniform(1.0, 3.0, (2000, 3))
    excess = 0.3 * added + rng.normal(0.0, 0.5 * np.sqrt(added))
    got = [held_share(x, h, np.full(3, 10.0)) for x, h in zip(excess, added, strict=True)]
    assert 0.92 <= np.mean([s.upper >= 0.3 for s in got]) <= 0.98
    assert np.mean([s.used == 0.0 for s in got]) < 0.015
    assert np.mean([s.point == 0.0 for s in got]) > 0.05


def test_the_held_block_says_when_the_prior_was_counted_unscaled():
    """Without folds the block counts the whole prior and says that no fold measured it, in its
    fields and in the report's words; measured, the words give the bound and the estimate."""
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.held_prior import held_block, held_sentence, held_share

    block = held_block(Deviation())
    assert block["share"] == 1.0 and block["share_basis"] == "no_folds"
    assert block["share_estimate"] is None
    assert "unscaled" in block["share_what"] and "no folds" in block["share_what"]
    assert "unscaled" in held_sentence(block) and "no folds" in held_sentence(block)
    measured = held_block(Deviation(), held_share(np.array([1.0, 3.0]), np.array([10.0, 20.0]),
                                                  np.full(2, 5.0)))  # fmt: skip
    assert measured["share_basis"] == "folds"
    assert measured["share_estimate"] == pytest.approx(4 / 30)
    words = held_sentence(measured)
    assert f"{measured['share']:.3g} of the prior of +-1 mm / +-0.5 deg" in words
    assert "the 2 folds' 0.133" in words
    nothing = held_block(Deviation(), held_share(np.ones(2), np.zeros(2), np.full(2, 5.0)))
    assert held_sentence(nothing) is None and held_sentence(None) is None


def test_grown_size_counts_each_frames_share_at_its_distance():
    """Frames whose pixel excess is the board route's variogram (their own share ``u`` at their
    distance, the fold's ``w`` at the mean distance) plus the excess's own noise: the growth is
    found and the size at the mean distance is the true one; a level alone shows no growth."""
    rng = np.random.default_rng(5)
    u, w = rng.uniform(1e6, 3e6, 40), rng.uniform(1e5, 3e5, 40)  # px^2 per m^2
    d = rng.uniform(0.02, 0.3, 40)
    reach = d.mean()
    var = np.full(40, 0.005**2)  # px^4: the excess's variance without a model error
    c0, c1 = (2e-5) ** 2, (5e-4) ** 2  # m^2, m^2 per squared distance
    clean = c0 * (u + w) + c1 * (u * d**2 + w * reach**2)
    m, at, gram = grown_size(clean + rng.normal(0, 0.005, 40), var, u, w, d)
    assert at == pytest.approx(reach) and gram is not None and gram.shown
    assert m == pytest.approx(np.sqrt(c0 + c1 * reach**2), rel=0.04)
    # the same level everywhere: no growth shown, its upper bound counted, the level the rest
    flat = 10 * c0 * (u + w) + rng.normal(0, 0.005, 40)
    m_flat, _, gram_flat = grown_size(flat, var, u, w, d)
    assert gram_flat is not None and not gram_flat.shown
    assert 0 < gram_flat.growth * reach**2 < 0.2 * gram_flat.level
    b = u * d**2 + w * reach**2
    assert gram_flat.level * (u + w).sum() + gram_flat.growth * b.sum() == pytest.approx(flat.sum())
    assert m_flat == pytest.approx(np.sqrt(np.sum(flat) / (u.sum() + w.sum())), rel=0.04)
    # without distances (no spans) the same everywhere
    m0, reach0, none = grown_size(clean, var, u, w, np.zeros(40))
    assert reach0 == 0.0 and none is None
    assert m0 == pytest.approx(np.sqrt(clean.sum() / (u.sum() + w.sum())))


def test_an_accuracy_block_keeps_the_model_errors_growth():
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    q_cal = np.random.default_rng(1).uniform(-0.5, 0.5, (5, robot.n))
    block = {
        "estimated": [param_names(minimal_indices(model.joint_types))[0]],
        "covariance_si": [[1e-8]],
        "model_error": {"position_mm": 0.05, "rotation_deg": 0.01, "reach_distance": 0.04},
        "calibration_postures_si": q_cal.tolist(),
        "joint_limits_si": robot.limits.tolist(),
        "T_tool_point_si": np.eye(4).tolist(),
    }
    em = board_error_model_from_json(block, model, "calibration.json")
    assert em.reach_distance == 0.04 and np.allclose(em.reach_postures, q_cal)
    assert np.allclose(em.reach_span, np.diff(robot.limits, axis=1)[:, 0])
    assert np.allclose(em.model_error_factor(q_cal), 0.0)
    # the spans its distances were measured in (joint_spans_si, session 22) are read as written;
    # without them (an older file, above) the full ranges it was measured in; malformed: refused
    spans = joint_spans(robot.limits, revolute_joints(model.joint_types))
    assert spans is not None and spans[4] == pytest.approx(2 * np.pi)  # the wrist roll: a turn
    em = board_error_model_from_json(block | spans_json(spans), model, "calibration.json")
    assert np.allclose(em.reach_span, spans)
    with pytest.raises(InputError, match="accuracy.joint_spans_si must be 5 positive"):
        board_error_model_from_json(block | {"joint_spans_si": [1.0] * 4}, model, "c.json")
    del block["model_error"]["reach_distance"]  # an older file: the same everywhere
    old = board_error_model_from_json(block, model, "calibration.json")
    assert old.reach_postures is None and np.allclose(old.model_error_factor(q_cal), 1.0)


def test_an_accuracy_block_keeps_how_the_folds_saw_the_model_error_grow():
    """The block written by ModelError.to_json carries the variogram's level share and how far
    it was measured; read back, a growth not shown is the same everywhere, a growth shown grows,
    and either is not measured beyond that distance."""
    from selfcal.calibration.accuracy import ModelError
    from selfcal.calibration.growth import Variogram

    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    q_cal = np.random.default_rng(1).uniform(-0.5, 0.5, (5, robot.n))
    flat = Variogram(level=1e-8, growth=0.0, estimate=-1e-9, shown=False, t=0.4)
    me = ModelError(1e-4, 1e-5, 5, 5, 0, 2e-4, 1e-4, 1e-4, 1e-4, 1e-5, 1e-5,
                    reach_distance=0.1, growth=flat, measured_to=0.3)  # fmt: skip
    js = me.to_json()
    assert js["constant_share"] == 1.0 and js["growth_shown"] is False
    assert js["measured_to_distance"] == 0.3 and "not measured" in js["beyond_measured"]
    block = {
        "estimated": [param_names(minimal_indices(model.joint_types))[0]],
        "covariance_si": [[1e-8]],
        "model_error": js,
        "calibration_postures_si": q_cal.tolist(),
        "joint_limits_si": robot.limits.tolist(),
    }
    em = board_error_model_from_json(block, model, "calibration.json")
    assert em.reach_floor == 1.0 and em.measured_to == 0.3
    assert np.allclose(em.model_error_factor(q_cal), 1.0)
    grown = Variogram(level=1e-8, growth=3e-8, estimate=2e-8, shown=True, t=3.1)
    block["model_error"] = dataclasses.replace(me, growth=grown).to_json()
    em = board_error_model_from_json(block, model, "calibration.json")
    assert em.reach_floor == pytest.approx(1e-8 / (1e-8 + 3e-8 * 0.01))
    assert em.measured_to == 0.3 and em.unmeasured(q_cal + 1.0).all()
    assert not em.unmeasured(q_cal).any()
    # the folds found no model error: how far they tested the model is kept all the same, and
    # beyond it the model error (none) is not measured; it does not grow
    none = dataclasses.replace(me, position_m=0.0, rotation_rad=0.0, reach_distance=0.0,
                               growth=None, measured_to=0.25)  # fmt: skip
    assert none.to_json()["measured_to_distance"] == 0.25
    block["model_error"] = none.to_json()
    em = board_error_model_from_json(block, model, "calibration.json")
    assert em.model_error_m == 0.0 and em.reach is None and em.measured_to == 0.25
    assert em.unmeasured(q_cal + 1.0).all() and not em.unmeasured(q_cal).any()
    assert np.allclose(em.model_error_factor(q_cal + 1.0), 1.0)
    never = dataclasses.replace(none, measured_to=None).to_json()  # not read: no limit
    assert "measured_to_distance" not in never
