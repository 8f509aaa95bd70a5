"""Run-to-run spread of a tracker calibration: the bootstrap over its rows (issue #29).

Would the same measurements, taken again at other postures of the same kind, give the same tool
point? The position / pose rows are resampled with replacement ``N`` times (distance rows stay),
each resample is calibrated with the same options, and its tool point is predicted at the
workspace sample's joint vectors (:func:`selfcal.kinematics.tool_error.workspace_sample`) and at
the calibration postures. The spread at a joint vector is the RMS distance (mm) of the
resamples' tool points from the calibration's own. The rows are put in the order of their joint
vectors before resampling, so the order of the rows in the file does not change the result.

It measures the estimation error the data allow, as the covariance does
(:mod:`selfcal.calibration.tracker.accuracy`), by refitting instead of to first order; a model
error that every resample shares does not spread.
"""

from __future__ import annotations

import warnings

import numpy as np

from selfcal.calibration.spread import BOOTSTRAP, REGIONS, Spread, region_spread, spread_line
from selfcal.calibration.tracker.identify import TrackerResult, identify_tracker
from selfcal.errors import EstimationError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.kinematics.tool_error import WorkspaceSample

__all__ = ["Spread", "bootstrap_spread", "spread_line"]

WHAT = (
    "bootstrap over the position / pose rows: RMS distance of the resampled calibrations' tool "
    "points from this calibration's, per joint vector (mm)"
)


def bootstrap_spread(
    model: MCPCModel,
    meas: TrackerMeasurements,
    res: TrackerResult,
    sample: WorkspaceSample,
    resamplings: int,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    seed: int = 0,
    **identify_kw,
) -> Spread | None:
    """The spread of ``res`` (:func:`identify_tracker` of ``model`` on ``meas``) over
    ``resamplings`` bootstrap resamples (module docstring); None without position / pose rows or
    when every resample failed. ``identify_kw``: the identification's further options."""
    if meas.m == 0 or resamplings < 1:
        return None
    order = np.lexsort(np.asarray(meas.q, dtype=float).T[::-1])
    sorted_meas = meas.with_rows(order)
    qs = {name: getattr(sample, name) for name in REGIONS[:3]}
    qs["calibration_postures"] = meas.q
    ref = {k: res.predict(q) for k, q in qs.items() if len(q)}
    sq = {k: np.zeros(len(v)) for k, v in ref.items()}
    rng = np.random.default_rng(seed)
    done = failed = 0
    for _ in range(resamplings):
        pick = rng.integers(0, meas.m, meas.m)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fit = identify_tracker(model, sorted_meas.with_rows(pick), sigma_t_m=sigma_t_m,
                                       sigma_r_rad=sigma_r_rad, **identify_kw)  # fmt: skip
        except EstimationError:
            failed += 1
            continue
        done += 1
        for k, p in ref.items():
            sq[k] += np.sum((fit.predict(qs[k]) - p) ** 2, axis=1)
    if done == 0:
        return None
    regions = region_spread({k: v / done for k, v in sq.items()})
    return Spread(done, failed, regions, WHAT, BOOTSTRAP)
