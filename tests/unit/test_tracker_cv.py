"""The k-fold held-out check of a tracker calibration against its fair nominal
(selfcal/calibration/tracker/cross_validation.py): folds by configuration, the held-out RMS of
a model that fits, and an over-fitted calibration said to be no gain."""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.tracker.sim import make_case, measure
from selfcal.calibration.tracker.cross_validation import (
    MAX_FOLDS,
    NO_GAIN,
    configuration_index,
    cross_validate,
    cross_validation_line,
    fit_folds,
    fold_index,
)
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.robot.definition import load_robot

SIGMA_M = 5e-5


def _meas(case, m: int, poses: bool = True, sigma: float = SIGMA_M, seed: int = 3):
    q = case.configurations(m, seed)
    xyz, R = measure(case, q, sigma, seed, poses=poses)
    return TrackerMeasurements(q, xyz, R)


def _cv(case, meas, sigma: float = SIGMA_M):
    folds = fit_folds(case.nominal, meas, sigma_t_m=sigma, sigma_r_rad=1e-4)
    return cross_validate(case.nominal, meas, folds, sigma_t_m=sigma, sigma_r_rad=1e-4)


def test_folds_leave_one_configuration_out_whatever_the_rows_order():
    """Rows at the same joints (a repeat, or within 0.1 deg on every joint) are one
    configuration and land in one fold; configurations are dealt to at most MAX_FOLDS folds,
    the labels following the joints, not the rows' order; a wrist-only move is a configuration
    of its own (the tool point moves)."""
    rng = np.random.default_rng(0)
    types = ("revolute",) * 5
    base = rng.uniform(-2.0, 2.0, (14, 5))
    wrist = base[0].copy()
    wrist[4] += 0.5  # the last joint alone moved: another tool point
    near = base[1] + np.radians(0.05)  # within 0.1 deg of configuration 1 on every joint
    q = np.vstack([base, base[:4], wrist, near])
    config = configuration_index(q, types)
    assert config.max() + 1 == 15  # 14 + the wrist move
    assert np.array_equal(config[14:18], config[:4]) and config[19] == config[1]
    assert config[18] != config[0]
    fold = fold_index(config, MAX_FOLDS)
    assert fold.max() == MAX_FOLDS - 1
    for c in range(15):  # every configuration's rows on one side of each fold
        assert len(set(fold[config == c])) == 1
    perm = rng.permutation(len(q))
    assert np.array_equal(configuration_index(q[perm], types), config[perm])
    # distinct rows: sorted by their joints, dealt in turn (the split the model error used)
    qd = rng.normal(size=(23, 5))
    assert (
        np.bincount(fold_index(configuration_index(qd, types), 10)).tolist() == [3, 3, 3] + [2] * 7
    )


def test_repeated_measurements_are_held_out_together():
    """6 postures of a 2-axis positioner measured 3 times each: 6 folds, each leaving out one
    posture's 3 rows (never a repeat on both sides); one posture measured 9 times gives no
    cross-validation."""
    case = make_case(load_robot("tests/data/positioner2.toml"), seed=3)
    q = np.repeat(case.configurations(6, 3), 3, axis=0)
    xyz, R = measure(case, q, SIGMA_M, 3, poses=True)
    meas = TrackerMeasurements(q, xyz, R)
    folds = fit_folds(case.nominal, meas, sigma_t_m=SIGMA_M, sigma_r_rad=1e-4)
    assert folds is not None and folds.k == 6 and folds.configurations == 6
    assert np.bincount(folds.fold).tolist() == [3] * 6
    assert all(len(set(folds.fold[3 * i : 3 * i + 3])) == 1 for i in range(6))
    cv = cross_validate(case.nominal, meas, folds, sigma_t_m=SIGMA_M, sigma_r_rad=1e-4)
    assert cv is not None and cv.rows + 3 * cv.failed == 18 and cv.folds == 6
    one = TrackerMeasurements(
        q[:1].repeat(9, axis=0), xyz[:1].repeat(9, axis=0), R[:1].repeat(9, axis=0)
    )
    assert fit_folds(case.nominal, one, sigma_t_m=SIGMA_M, sigma_r_rad=1e-4) is None


def test_a_robot_off_nominal_is_supported_and_one_as_built_is_not():
    """8 poses of a 2-axis positioner with every parameter off by up to 1 mm / 0.2 deg: the
    calibration predicts the held-out rows better (8 configurations, 8 folds: each left out in
    turn; measured 0.113 mm and 0.0011 deg against the nominal's 0.48 mm and 0.12 deg). 8
    positions of one built exactly to nominal (only the tracker frame and the tool unknown):
    its extra parameters fit the noise, and the check says the data do not support them."""
    robot = load_robot("tests/data/positioner2.toml")
    case = make_case(robot, seed=3)
    off = _cv(case, _meas(case, 8))
    assert off is not None and off.rows == 8 and off.failed == 0 and off.folds == 8
    assert off.supported and off.rms_mm < off.nominal_rms_mm / 2
    assert off.rms_deg < off.nominal_rms_deg / 10
    exact_case = make_case(robot, seed=3, translation_mm=0.0, rotation_deg=0.0)
    exact = _cv(exact_case, _meas(exact_case, 8, poses=False))
    assert exact is not None and not exact.supported
    assert np.isnan(exact.rms_deg) and exact.to_json()["rms_deg"] is None
    # the nominal predicts near the noise, sqrt(3) sigma = 0.087 mm: measured 0.132 mm (9 of its
    # parameters from 7 rows), the calibration 0.169 mm
    assert exact.nominal_rms_mm < 2 * np.sqrt(3) * SIGMA_M * 1e3
    assert exact.rms_mm > exact.nominal_rms_mm


def test_a_model_that_fits_is_held_out_at_the_noise_of_a_fit_of_its_size():
    """ER-4u, 30 positions (more than the 20 rows the leave-one-out check took), the chain off
    by up to 1 mm / 0.2 deg, 0.1 mm noise: the 10-fold held-out RMS of the position error is
    that of a least-squares prediction, sqrt(3) sigma sqrt(1 + p / n) with p the estimated
    parameters and n the equations a fold is fitted to (measured per draw 0.90, 0.95, 1.18,
    1.03 of it, pooled 1.02); the fair nominal misses by the chain's error (1.2-2.7 mm)."""
    robot = load_robot("er4u-paper")
    sigma, m, ratios = 1e-4, 30, []
    for seed in range(1, 5):
        case = make_case(robot, seed=seed)
        meas = _meas(case, m, poses=False, sigma=sigma, seed=seed)
        p = int(identify_tracker(case.nominal, meas, sigma_t_m=sigma).estimated.sum())
        cv = _cv(case, meas, sigma)
        assert cv is not None and cv.folds == 10 and cv.rows == m and cv.supported
        assert cv.nominal_rms_mm > 5 * cv.rms_mm
        expected = np.sqrt(3) * sigma * 1e3 * np.sqrt(1 + p / (3 * m * 0.9))
        ratios.append(cv.rms_mm / expected)
    assert all(0.67 < r < 1.5 for r in ratios), ratios
    assert 0.85 < np.sqrt(np.mean(np.square(ratios))) < 1.15, ratios


def test_an_over_fitted_calibration_is_reported_no_better_than_the_fair_nominal():
    """ER-4u built exactly to its drawing, 15 positions at 0.1 mm: the calibration's 23
    parameters fit the noise; held out it predicts worse than the fair nominal (measured
    0.281 mm against 0.193 mm), and the line says NO GAIN."""
    case = make_case(load_robot("er4u-paper"), seed=1, translation_mm=0.0, rotation_deg=0.0)
    cv = _cv(case, _meas(case, 15, poses=False, sigma=1e-4, seed=1), 1e-4)
    assert cv is not None and cv.rows == 15 and not cv.supported
    assert cv.rms_mm > 1.2 * cv.nominal_rms_mm
    line = cross_validation_line(cv.to_json())
    assert line is not None and line.endswith(NO_GAIN.format(what="position"))
    assert (
        f"held-out RMS calibrated {cv.rms_mm:.4f} mm; fair nominal {cv.nominal_rms_mm:.4f}" in line
    )


def test_too_few_rows_give_no_check():
    """3 positions: every fold leaves 2 (6 equations for 11 parameters), none is fitted."""
    case = make_case(load_robot("tests/data/positioner2.toml"), seed=3)
    assert _cv(case, _meas(case, 3, poses=False)) is None
    assert cross_validation_line(None) is None


def test_a_leave_one_out_block_of_an_older_file_still_reads():
    """calibration.json written before the k-fold check (leave-one-out up to 20 rows, no
    ``folds``): report.md says what it was."""
    old = {"rows": 8, "rms_mm": 0.118, "nominal_rms_mm": 0.335, "rms_deg": None,
           "nominal_rms_deg": None, "failed_folds": 0, "supported": True}  # fmt: skip
    assert cross_validation_line(old) == (
        "leave-one-out over 8 rows: held-out RMS calibrated 0.1180 mm; fair nominal 0.3350 mm"
    )


def test_no_gain_names_what_is_not_better():
    """Poses whose positions gain but whose orientations do not: NO GAIN names the
    orientation alone."""
    block = {"rows": 20, "folds": 10, "configurations": 20, "rms_mm": 0.1, "nominal_rms_mm": 0.5,
             "rms_deg": 0.02, "nominal_rms_deg": 0.01, "failed_folds": 0, "supported": False}  # fmt: skip
    line = cross_validation_line(block)
    assert line is not None and line.endswith(
        "0.1000 mm, 0.0200 deg; fair nominal 0.5000 mm, 0.0100 deg; NO GAIN: held out, the "
        "calibration's orientation error is no smaller than the fair nominal's"
    )
