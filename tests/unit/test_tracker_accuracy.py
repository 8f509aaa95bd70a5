"""The predicted tool-point accuracy of a tracker calibration (issue #29)."""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from selfcal.benchmarks.tracker.sim import make_case, measure
from selfcal.calibration.tracker.accuracy import (
    error_model_from_json,
    postures_from_json,
    tracker_accuracy,
)
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.errors import InputError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot

SIGMA = 1e-4


@pytest.fixture(scope="module")
def er4u():
    return load_robot("er4u-paper")


def _calibrate(robot, q, xyz, R=None):
    case_nominal = make_case(robot, seed=5).nominal
    meas = TrackerMeasurements(q, xyz, R, None, None, None)
    res = identify_tracker(case_nominal, meas, sigma_t_m=SIGMA)
    acc = tracker_accuracy(case_nominal, meas, res, robot.limits, sigma_t_m=SIGMA,
                           sigma_r_rad=1e-4, count=128)  # fmt: skip
    return res, acc


def _true_errors(case, acc, q):
    pred = acc.error_model.predicted(q)
    e = np.linalg.norm(pred["position_mm"] - fk_tool(case.true, q)[:, :3, 3] * 1e3, axis=1)
    return pred, e


def test_a_model_that_fits_predicts_its_error(er4u):
    """No misfit: a small model error; over the workspace the 95 % bound covers the true error
    at most points and the predicted RMS is near the true one (one draw: slice 2's benchmark
    measures it over many)."""
    case = make_case(er4u, seed=5)
    q = case.configurations(30, 6)
    xyz, _ = measure(case, q, SIGMA, 7)
    _, acc = _calibrate(er4u, q, xyz)
    assert acc.model_error is not None and acc.model_error.folds == 10
    assert acc.model_error.position_m < 0.5 * SIGMA
    qw = case.configurations(300, 8)
    pred, e = _true_errors(case, acc, qw)
    assert np.mean(e <= pred["position_95_mm"]) > 0.85
    ratio = np.sqrt(np.mean(pred["position_rms_mm"] ** 2) / np.mean(e**2))
    assert 0.7 < ratio < 1.5


def test_a_misfit_enters_as_model_error(er4u):
    """A joint compliance the chain cannot express (joint 2 bends by 0.1 deg x cos(q2 + q3)):
    the covariance alone covers the true error at few points, with the model error at most."""
    case = make_case(er4u, seed=5)
    q = case.configurations(30, 6)

    def bent(q):
        qb = q.copy()
        qb[:, 1] += np.radians(0.1) * np.cos(q[:, 1] + q[:, 2])
        return qb

    xyz = fk_tool(case.true, bent(q))[:, :3, 3] + np.random.default_rng(7).normal(0, SIGMA, (30, 3))
    res, acc = _calibrate(er4u, q, xyz)
    assert acc.model_error.position_m > SIGMA
    # how it grows was read from the folds (growth.py) and the block rebuilds it
    me = acc.model_error
    assert me.growth is not None and me.reach_distance > 0 and 0 <= me.reach_floor < 1
    assert acc.error_model.reach is not None
    em = error_model_from_json(acc.to_json(), res.model, res.T_meas_fit, res.names, False, "c")
    qw = case.configurations(300, 8)
    assert np.allclose(em.predicted(qw)["position_95_mm"],
                       acc.error_model.predicted(qw)["position_95_mm"], rtol=1e-12)  # fmt: skip
    pred = acc.error_model.predicted(qw)
    e = np.linalg.norm(pred["position_mm"] - fk_tool(case.true, bent(qw))[:, :3, 3] * 1e3, axis=1)
    covered = np.mean(e <= pred["position_95_mm"])
    covariance_alone = np.mean(e <= pred["estimation_95_mm"])
    assert covered > 0.75 and covariance_alone < covered - 0.1


def _rebuilt(er4u, poses: bool):
    case = make_case(er4u, seed=5)
    q = case.configurations(25, 6)
    xyz, R = measure(case, q, SIGMA, 7, poses=poses)
    res, acc = _calibrate(er4u, q, xyz, R)
    block = acc.to_json()
    em = error_model_from_json(block, res.model, res.T_meas_fit, res.names, poses, "cal.json")
    assert np.array_equal(postures_from_json(block, er4u.n, "cal.json"), q)
    qw = case.configurations(20, 9)
    got, want = em.predicted(qw), acc.error_model.predicted(qw)
    for key in ("position_95_mm", "orientation_95_deg"):
        assert np.allclose(got[key], want[key], rtol=1e-12, equal_nan=True)
    return res, acc, block


def test_the_block_rebuilds_the_prediction(er4u):
    res, acc, block = _rebuilt(er4u, poses=False)
    assert block["model_error"]["rotation_deg"] is None
    assert "orientation_95_deg_max" not in acc.summary["inside"]
    block["estimated"] = block["estimated"][:-1]
    with pytest.raises(InputError, match="does not match its parameters"):
        error_model_from_json(block, res.model, res.T_meas_fit, res.names, False, "cal.json")


@pytest.mark.slow
def test_a_fit_of_poses_predicts_the_orientation_too(er4u):
    """Slow: 11 identifications of poses take 2-5 s on a loaded 2-core machine."""
    _, acc, block = _rebuilt(er4u, poses=True)
    assert block["model_error"]["rotation_deg"] is not None
    assert acc.summary["inside"]["orientation_95_deg_max"] > 0


def test_the_order_of_the_rows_does_not_matter(er4u):
    case = make_case(er4u, seed=5)
    q = case.configurations(24, 6)
    xyz, _ = measure(case, q, SIGMA, 7)
    perm = np.random.default_rng(1).permutation(24)
    _, a = _calibrate(er4u, q, xyz)
    _, b = _calibrate(er4u, q[perm], xyz[perm])
    ma, mb = (
        np.array([v for v in astuple(x.model_error) if not isinstance(v, str)], dtype=float)
        for x in (a, b)
    )  # None -> nan
    assert np.allclose(ma, mb, rtol=1e-6, equal_nan=True)
    for region in ("inside", "edge", "workspace"):
        for key, v in a.summary[region].items():
            assert b.summary[region][key] == pytest.approx(v, rel=1e-6), (region, key)


def test_the_held_out_test_counts_an_excess_beyond_two_standard_errors():
    """The excess of the held-out squared norms over what the estimate and the noise explain, in
    standard errors of their mean under no model error (2/3 of the square mean over the rows),
    and the smallest model error the test counts: 6 rows expecting 1 have a standard error of
    1/3, so 2 is 3 standard errors (counted, sqrt(1/3) per coordinate) and 1.5 is 1.5 (not);
    the smallest counted is sqrt(2 / 3 / 3)."""
    from selfcal.calibration.accuracy import Z_MODEL_ERROR, excess, excess_test

    assert Z_MODEL_ERROR == 2.0
    assert excess_test(2.0, 1.0, 6) == pytest.approx((3.0, np.sqrt(2.0 / 9.0)))
    assert excess(2.0, 1.0, 6) == pytest.approx(np.sqrt(1.0 / 3.0))
    assert excess_test(1.5, 1.0, 6)[0] == pytest.approx(1.5) and excess(1.5, 1.0, 6) == 0.0
    assert excess_test(1.0, 0.0, 6)[0] == np.inf and excess(1.0, 0.0, 6) == pytest.approx(
        np.sqrt(1.0 / 3.0)
    )
    assert excess_test(0.0, 0.0, 6)[0] == -np.inf and excess(0.0, 0.0, 6) == 0.0
