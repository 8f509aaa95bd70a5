"""The tracker route in one call: tracker measurement files -> the identified chain, the fair
nominal beside it, the k-fold held-out check against it, the predicted tool-point accuracy over the workspace
and the ``calibration.json`` content
(:mod:`selfcal.calibration.tracker.calibration_file`). ``selfcal identify`` prints and writes
what :func:`calibrate_tracker` returns; the public API serves it as ``selfcal.calibrate_tracker``.

File formats: :mod:`selfcal.io.tracker` and docs/tracker.md. SI inside; the files' joints in
``joint_units`` (``deg``: revolute joints in degrees, prismatic in mm; ``rad``: radians and
metres), positions in mm, the tracker's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from selfcal.calibration.tracker.accuracy import TrackerAccuracy, tracker_accuracy
from selfcal.calibration.tracker.calibration_file import TrackerCalibration, from_result
from selfcal.calibration.tracker.cross_validation import (
    CrossValidation,
    cross_validate,
    fit_folds,
)
from selfcal.calibration.tracker.identify import (
    TrackerMeasurements,
    TrackerResult,
    identify_tracker,
)
from selfcal.calibration.tracker.nominal import NominalFit, fit_nominal
from selfcal.calibration.tracker.spread import Spread, bootstrap_spread
from selfcal.errors import InputError
from selfcal.io.tracker import Table
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.terms.tracker import read_tracker_files
from selfcal.threads import limited

__all__ = ["TrackerRun", "calibrate_tracker", "read_tracker_files"]


@dataclass(frozen=True)
class TrackerRun:
    """What :func:`calibrate_tracker` found: the ``result`` (the identified chain, tracker
    frame), the ``calibration`` (the ``calibration.json`` content, mm and deg), the ``nominal``
    fit (the robot file's chain, tracker frame and tool fitted the same way), the k-fold
    ``cross_validation`` of both (:mod:`selfcal.calibration.tracker.cross_validation`; None
    with fewer than 2 configurations of position / pose rows or when no fold could be
    fitted), the ``measurements`` (SI)
    and the measurements file's ``table``; the predicted tool-point ``accuracy`` over the
    workspace (:mod:`selfcal.calibration.tracker.accuracy`, also ``calibration.accuracy``; None
    without position / pose rows) and the run-to-run ``spread`` of the tool point over bootstrap
    resamplings of the rows (:mod:`selfcal.calibration.tracker.spread`, also
    ``calibration.accuracy["spread"]``; None unless asked for)."""

    result: TrackerResult
    calibration: TrackerCalibration
    nominal: NominalFit
    cross_validation: CrossValidation | None
    measurements: TrackerMeasurements
    table: Table
    accuracy: TrackerAccuracy | None = None
    spread: Spread | None = None


@limited
def calibrate_tracker(
    measurements: str | Path,
    robot: str | Path,
    joint_units: str,
    *,
    distances: str | Path | None = None,
    sigma_mm: float = 0.1,
    sigma_deg: float = 0.01,
    hold: tuple[str, ...] | list[str] = (),
    trust_units: bool = False,
    spread: int = 0,
) -> TrackerRun:
    """Identify ``robot``'s kinematics (a model name, robot TOML or URDF) from the tracker
    measurements file ``measurements`` (tool-point positions or poses, mm, tracker frame) and
    the optional ball-bar ``distances`` file, as ``selfcal identify`` does; nothing is written
    (:func:`selfcal.calibration.routes.write_calibration` writes ``run.calibration``).

    Args:
        joint_units: ``deg`` (revolute degrees, prismatic mm) or ``rad`` (radians, metres).
        sigma_mm: position and distance noise, mm; ``sigma_deg``: orientation noise of poses,
            deg (they weigh the kinds against each other).
        hold: minimal parameter names held at nominal.
        trust_units: skip the check that degrees look like radians.
        spread: this many bootstrap resamplings of the rows for the run-to-run spread of the
            tool point (one identification each); 0: none.

    Raises:
        InputError: a noise that is not a positive number, a negative ``spread`` or a file
            that cannot be read (named with row and column).
        TrackerIdentificationError: too few measurements for what they can identify (says how
            many are needed).
    """
    for name, v in (("sigma_mm", sigma_mm), ("sigma_deg", sigma_deg)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v}")
    if spread < 0:
        raise InputError(f"spread must be a number of resamplings >= 0, got {spread}")
    rd = load_robot(robot)
    meas, table = read_tracker_files(measurements, distances, rd, joint_units,
                                     guess=not trust_units)  # fmt: skip
    nominal = nominal_mcpc(rd)
    s_t, s_r = sigma_mm / 1e3, float(np.radians(sigma_deg))
    res = identify_tracker(nominal, meas, sigma_t_m=s_t, sigma_r_rad=s_r, sigma_d_m=s_t, hold=hold)
    fair = fit_nominal(nominal, meas, sigma_t_m=s_t, sigma_r_rad=s_r)
    # one set of fold fits: the model error of the predicted accuracy and the held-out check
    folds = fit_folds(nominal, meas, sigma_t_m=s_t, sigma_r_rad=s_r, sigma_d_m=s_t, hold=hold)
    cv = cross_validate(nominal, meas, folds, sigma_t_m=s_t, sigma_r_rad=s_r)
    acc = tracker_accuracy(nominal, meas, res, rd.limits, sigma_t_m=s_t, sigma_r_rad=s_r,
                           fold_fits=folds, sigma_d_m=s_t, hold=hold)  # fmt: skip
    cal = from_result(
        res,
        nominal,
        robot=rd.name,
        robot_source=str(robot),
        joint_names=rd.joint_names,
        joint_limits=rd.limits,
        joint_units=joint_units,
        sigmas={"position_mm": sigma_mm, "rotation_deg": sigma_deg, "distance_mm": sigma_mm},
        files={
            "measurements": str(measurements),
            "distances": None if distances is None else str(distances),
        },
        fair_nominal=fair,
    )
    if cv is not None:
        cal.fit["cross_validation"] = cv.to_json()
    boot = None
    if acc is not None:
        block = acc.to_json()
        if spread > 0:
            boot = bootstrap_spread(nominal, meas, res, acc.sample, spread, sigma_t_m=s_t,
                                    sigma_r_rad=s_r, sigma_d_m=s_t, hold=hold)  # fmt: skip
            block["spread"] = None if boot is None else boot.to_json()
        cal = replace(cal, accuracy=block)
    return TrackerRun(res, cal, fair, cv, meas, table, acc, boot)
