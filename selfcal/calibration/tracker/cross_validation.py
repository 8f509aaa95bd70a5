"""Leave-one-configuration-out check of a tracker calibration against its fair nominal.

The fit RMS of a calibration on its own rows always beats the fair nominal's
(:mod:`selfcal.calibration.tracker.nominal`): it has more parameters. Whether the data support those
parameters shows on rows the fit did not see. For a small set (few configurations, where the
question matters and the folds are cheap) each position / pose row is left out in turn, the
calibration (:func:`selfcal.calibration.tracker.identify.identify_tracker`, the same options) and the fair
nominal are fitted to the others, and both predict the row left out. Distance rows stay in
every fold.

Units: SI inside; ``_mm`` / ``_deg`` fields for reports.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.calibration.tracker.nominal import fit_nominal, pose_errors
from selfcal.errors import EstimationError
from selfcal.estimation.tracker import TrackerMeasurements

__all__ = ["CrossValidation", "leave_one_out", "MAX_ROWS"]

MAX_ROWS = 20
"""Sets of at most this many position / pose rows are cross-validated by :func:`leave_one_out`
(a fold is one identification: milliseconds for small robots)."""


@dataclass(frozen=True)
class CrossValidation:
    """Leave-one-out prediction errors (RMS over the rows left out).

    Attributes:
        rows: how many rows were left out in turn.
        rms_mm, nominal_rms_mm: position error of the calibration and of the fair nominal (mm).
        rms_deg, nominal_rms_deg: rotation error (deg) for poses, else nan.
        failed: folds whose identification failed (too few rows left); their rows are not
            counted.
    """

    rows: int
    rms_mm: float
    nominal_rms_mm: float
    rms_deg: float
    nominal_rms_deg: float
    failed: int

    def to_json(self) -> dict:
        """The figures for calibration.json (null for nan)."""

        def num(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "what": "leave one configuration out: the calibration and the fair nominal fitted to "
            "the others predict it",
            "rows": self.rows,
            "rms_mm": num(self.rms_mm),
            "nominal_rms_mm": num(self.nominal_rms_mm),
            "rms_deg": num(self.rms_deg),
            "nominal_rms_deg": num(self.nominal_rms_deg),
            "failed_folds": self.failed,
            "supported": self.supported,
        }

    @property
    def supported(self) -> bool:
        """Whether the calibration predicts the left-out rows better than the nominal (position,
        and rotation for poses)."""
        better = self.rms_mm < self.nominal_rms_mm
        if np.isfinite(self.rms_deg):
            better = better and self.rms_deg < self.nominal_rms_deg
        return bool(better)


def _rms(v: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(v)))) if v else float("nan")


def leave_one_out(
    model, meas: TrackerMeasurements, *, sigma_t_m: float, sigma_r_rad: float, **identify_kw
) -> CrossValidation | None:
    """Leave each position / pose row of ``meas`` out in turn (module docstring); None when
    there are none or more than :data:`MAX_ROWS`, or when no fold could be identified.
    ``identify_kw``: further options of :func:`identify_tracker` (``sigma_d_m``, ``hold``)."""
    if not 0 < meas.m <= MAX_ROWS:
        return None
    errs: dict[str, list[float]] = {"pos": [], "rot": [], "npos": [], "nrot": []}
    failed = 0
    for i in range(meas.m):
        keep = np.arange(meas.m) != i
        train = meas.with_rows(keep)
        try:
            with warnings.catch_warnings():  # a fold's own rank notes: the whole fit has its own
                warnings.simplefilter("ignore")
                res = identify_tracker(
                    model, train, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad, **identify_kw
                )
            nom = fit_nominal(model, train, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad)
        except EstimationError:
            failed += 1
            continue
        R = None if meas.R is None else meas.R[i : i + 1]
        for key, T in (("", res.predict_poses(meas.q[i])), ("n", nom.predict_poses(meas.q[i]))):
            pos, ang = pose_errors(T, meas.xyz[i : i + 1], R)
            errs[key + "pos"].append(float(pos[0]))
            if ang is not None:
                errs[key + "rot"].append(float(ang[0]))
    if failed == meas.m:
        return None
    return CrossValidation(
        rows=meas.m - failed,
        rms_mm=_rms(errs["pos"]),
        nominal_rms_mm=_rms(errs["npos"]),
        rms_deg=_rms(errs["rot"]),
        nominal_rms_deg=_rms(errs["nrot"]),
        failed=failed,
    )
