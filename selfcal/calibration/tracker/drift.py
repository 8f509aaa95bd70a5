"""Drift check: do new tracker measurements still fit a tracker calibration? (issue #29)

New rows (joint readings and measured tool points, any postures) are compared with the
calibration's prediction. Under "unchanged" the residuals ``r = measured - predicted`` (3k,
tracker frame) are Gaussian with covariance

    Sigma = J C J^T + (m^2 + nu^2) I

(:class:`selfcal.kinematics.tool_error.ToolErrorModel`: ``J C J^T`` the calibration's estimation
error at the new postures, correlated between them through the shared parameters; ``m`` the
model error and ``nu`` the tracker noise per coordinate, both from the calibration's
``accuracy`` block). The statistic ``T = r^T Sigma^-1 r`` is then chi-square with ``3k`` degrees
of freedom; the robot has changed when ``P(chi2_3k >= T) < alpha`` (0.01). The size of the change
is the RMS of the residuals beyond what ``Sigma`` explains (mm at the tool), and their mean
(a shift of the whole cell, the tracker or the base, shows there). Positions only: a calibration
fitted to poses is checked on the positions of its tool frame's origin.

:func:`check_tracker` is the whole check from the files (``selfcal check`` and the public API):
the calibration folder of ``selfcal identify`` and a new measurements file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from selfcal.calibration.drift.p_value import p_text
from selfcal.calibration.tracker.accuracy import error_model_from_json
from selfcal.calibration.tracker.calibration_file import (
    is_tracker_calibration,
    read_tracker_calibration,
)
from selfcal.errors import InputError
from selfcal.io.tracker import read_measurements
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.threads import limited

__all__ = ["ALPHA", "DriftCheck", "drift_check", "check_tracker"]

ALPHA = 0.01
"""The false-alarm probability the check allows on an unchanged robot."""


@dataclass(frozen=True)
class DriftCheck:
    """Outcome of :func:`drift_check` (mm).

    Attributes:
        rows: new rows compared; statistic, dof, p_value: the chi-square test.
        changed: ``p_value < alpha``.
        rms_mm: RMS of the residuals' norms; expected_rms_mm: what ``Sigma`` predicts for it
            (``sqrt(tr Sigma / k)``); change_mm: the RMS beyond it (0 when below).
        mean_mm: (3,) mean residual in the tracker frame.
        alpha: the test's level.
    """

    rows: int
    statistic: float
    dof: int
    p_value: float
    changed: bool
    rms_mm: float
    expected_rms_mm: float
    change_mm: float
    mean_mm: np.ndarray
    alpha: float

    def line(self) -> str:
        """The verdict in one line."""
        if self.changed:
            return (
                f"changed by {self.change_mm:.3f} mm at the tool (RMS over {self.rows} new rows "
                f"beyond the predicted {self.expected_rms_mm:.3f} mm; {p_text(self.p_value)} < "
                f"{self.alpha:g})"
            )
        return (
            f"unchanged: {self.rows} new rows within the calibration's prediction "
            f"({self.rms_mm:.3f} mm RMS, predicted {self.expected_rms_mm:.3f} mm; "
            f"{p_text(self.p_value)})"
        )

    def to_json(self) -> dict:
        """The result as JSON (mm)."""
        return {
            "verdict": "changed" if self.changed else "unchanged",
            "line": self.line(),
            "rows": self.rows,
            "statistic": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "alpha": self.alpha,
            "rms_mm": self.rms_mm,
            "expected_rms_mm": self.expected_rms_mm,
            "change_mm": self.change_mm,
            "mean_mm": self.mean_mm.tolist(),
        }


def drift_check(
    em: ToolErrorModel, q: np.ndarray, xyz_m: np.ndarray, noise_m: float, *, alpha: float = ALPHA
) -> DriftCheck:
    """Check the new rows ``q`` (k, n) rad / m, ``xyz_m`` (k, 3) m (tracker frame) against the
    calibration ``em`` with the tracker noise ``noise_m`` per coordinate (module docstring).

    Raises:
        InputError: no rows, or shapes that do not match.
    """
    q, xyz_m = np.atleast_2d(q), np.atleast_2d(xyz_m)
    k = len(q)
    if k == 0 or xyz_m.shape != (k, 3):
        raise InputError(f"drift check: {k} joint rows against positions of shape "
                         f"{xyz_m.shape}", fix="give one measured position per joint row")  # fmt: skip
    r = (xyz_m - em.tool_positions(q)).reshape(-1)
    Jp = em.jacobian(q)[:, :3].reshape(3 * k, -1)
    m2 = np.repeat(em.model_error_m**2 * em.model_error_factor(q), 3)  # grown at each row's q
    sigma = Jp @ em.covariance @ Jp.T + np.diag(m2 + noise_m**2)
    T = float(r @ np.linalg.solve(sigma, r))
    p = float(chi2.sf(T, 3 * k))
    rms2 = float(np.sum(r**2) / k)
    exp2 = float(np.trace(sigma) / k)
    return DriftCheck(
        rows=k,
        statistic=T,
        dof=3 * k,
        p_value=p,
        changed=p < alpha,
        rms_mm=np.sqrt(rms2) * 1e3,
        expected_rms_mm=np.sqrt(exp2) * 1e3,
        change_mm=np.sqrt(max(0.0, rms2 - exp2)) * 1e3,
        mean_mm=r.reshape(k, 3).mean(axis=0) * 1e3,
        alpha=alpha,
    )


@limited
def check_tracker(
    calibration: str | Path,
    new_data: str | Path,
    joint_units: str,
    *,
    alpha: float = ALPHA,
    trust_units: bool = False,
) -> DriftCheck:
    """Check the new tracker measurements file ``new_data`` (any postures, a few rows; the
    format ``selfcal identify`` reads, joints in ``joint_units``, positions mm; orientation
    columns are not compared) against the tracker calibration ``calibration`` (the folder of
    ``selfcal identify`` or its ``calibration.json``), with the calibration's ``accuracy`` block
    and the position noise stated to ``identify`` (module docstring). ``trust_units``: skip the
    check that degrees look like radians.

    Raises:
        InputError: the calibration is missing, not a tracker calibration or has no accuracy
            block; ``alpha`` is not a probability; the new file cannot be read (named with row
            and column).
    """
    src = Path(calibration)
    path = src / "calibration.json" if src.is_dir() else src
    if not path.is_file():
        raise InputError(f"{path} not found", fix="give the DIR `selfcal identify --out DIR` wrote")
    if not is_tracker_calibration(path):
        raise InputError(
            f"{path} is not a tracker calibration: only those of `selfcal identify` are checked "
            "so far",
            fix="calibrate from tracker measurements with `selfcal identify`",
        )
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha {alpha} is not a probability", fix="e.g. alpha 0.01")
    cal = read_tracker_calibration(path)
    if cal.accuracy is None:
        raise InputError(
            f"{path} has no accuracy block (written before it, or fitted to distances alone)",
            fix="re-run `selfcal identify` with position or pose rows",
        )
    meas, _ = read_measurements(new_data, cal, joint_units, guess=not trust_units)
    em = error_model_from_json(cal.accuracy, cal.model, cal.T_meas_fit, cal.names, cal.poses,
                               str(path))  # fmt: skip
    noise_m = float(cal.sigmas["position_mm"]) / 1e3  # as stated to identify
    return drift_check(em, meas.q, meas.xyz, noise_m, alpha=alpha)
