"""The run-to-run spread of a tracker calibration over bootstrap resamples (issue #29)."""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.tracker.sim import make_case, measure
from selfcal.calibration.tracker.accuracy import tracker_accuracy
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.calibration.tracker.spread import bootstrap_spread, spread_line
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.robot.definition import load_robot

SIGMA = 1e-4


def _spread(q, xyz, robot, nominal, n=20):
    meas = TrackerMeasurements(q, xyz, None, None, None, None)
    res = identify_tracker(nominal, meas, sigma_t_m=SIGMA)
    acc = tracker_accuracy(nominal, meas, res, robot.limits, sigma_t_m=SIGMA, sigma_r_rad=1e-4,
                           count=64)  # fmt: skip
    kw = {"sigma_t_m": SIGMA, "sigma_r_rad": 1e-4}
    return acc, bootstrap_spread(nominal, meas, res, acc.sample, n, **kw)


def test_the_spread_is_the_estimation_error_and_ignores_the_rows_order():
    """Without misfit the bootstrap's spread is near what the covariance predicts (RMS over the
    calibrated region); shuffling the rows gives the same spread."""
    robot = load_robot("er4u-paper")
    case = make_case(robot, seed=5)
    q = case.configurations(30, 6)
    xyz, _ = measure(case, q, SIGMA, 7)
    acc, spread = _spread(q, xyz, robot, case.nominal)
    assert spread.resamplings + spread.failed == 20
    predicted = acc.summary["inside"]["position_rms_mm"]
    s = spread.regions["inside"]["spread_mm_median"]
    assert 0.5 * predicted < s < 1.5 * predicted
    perm = np.random.default_rng(2).permutation(30)
    _, again = _spread(q[perm], xyz[perm], robot, case.nominal)
    for region, values in spread.regions.items():
        for key, v in values.items():
            assert abs(again.regions[region][key] - v) < 1e-9 * v, (region, key)
    line = spread_line(spread.to_json())
    assert f"{spread.regions['inside']['spread_mm_max']:.3f} mm RMS at most inside" in line
