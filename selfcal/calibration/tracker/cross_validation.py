"""The cross-validation folds of a tracker calibration and its k-fold held-out check against the
fair nominal (issue #29).

The fit RMS of a calibration on its own rows always beats the fair nominal's
(:mod:`selfcal.calibration.tracker.nominal`): it has more parameters. Whether the data support those
parameters shows on rows the fit did not see. The position / pose rows are grouped into
configurations (rows whose joints are all within 0.1 deg / 0.1 mm of each other, the board
route's rule with every joint counted: :func:`selfcal.calibration.board.folds.configurations`),
numbered in the lexicographic order of their joints, and configuration ``c`` goes to fold
``c % K`` with ``K = min(configurations, MAX_FOLDS)``: one configuration left out at a time up
to :data:`MAX_FOLDS` configurations, a repeated measurement never on both sides of a fold, and
the split independent of the rows' order. Each fold's rows are predicted by the calibration
(:func:`selfcal.calibration.tracker.identify.identify_tracker`, the same options) fitted to the
others (:func:`fit_folds`, the fits the model error of
:mod:`selfcal.calibration.tracker.accuracy` reads too) and by the fair nominal fitted to the
same others (:func:`cross_validate`); distance rows stay in every fold. A fold counts when both
fits succeed (a fold whose rest is too few to identify the chain does not).

Units: SI inside; ``_mm`` / ``_deg`` fields for reports.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.folds import configurations
from selfcal.calibration.tracker.identify import TrackerResult, identify_tracker
from selfcal.calibration.tracker.nominal import fit_nominal, pose_errors
from selfcal.errors import EstimationError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.mcpc import MCPCModel

__all__ = [
    "MAX_FOLDS",
    "CrossValidation",
    "FoldFits",
    "configuration_index",
    "cross_validate",
    "cross_validation_line",
    "fit_folds",
    "fold_index",
]

MAX_FOLDS = 10
"""At most this many cross-validation folds (one identification and one fair nominal each)."""


def configuration_index(q: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
    """(m,) the configuration of every row of the joints ``q`` (m, n) rad / m: rows whose joints
    are all within 0.1 deg / 0.1 mm share one, numbered in the lexicographic order of the joints
    (module docstring)."""
    return configurations(q, joint_types, whole=True)


def fold_index(config: np.ndarray, k: int) -> np.ndarray:
    """(m,) the fold of every row of the configurations ``config`` (m,)
    (:func:`configuration_index`): configuration ``c`` to fold ``c % k``, so a configuration's
    rows are left out together and the split does not depend on the rows' order."""
    return np.asarray(config, dtype=int) % k


@dataclass(frozen=True)
class FoldFits:
    """The folds of a tracker calibration's cross-validation and the calibration fitted to each
    fold's rest (module docstring).

    Attributes:
        fold: (m,) the fold of every position / pose row.
        k: the number of folds.
        configurations: the number of distinct configurations among the rows.
        fits: fold -> the identification on the other folds' rows (absent: it failed).
    """

    fold: np.ndarray
    k: int
    configurations: int
    fits: dict[int, TrackerResult]

    @property
    def failed(self) -> int:
        """Folds whose identification failed."""
        return self.k - len(self.fits)


def fit_folds(
    model: MCPCModel,
    meas: TrackerMeasurements,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    folds: int = MAX_FOLDS,
    **identify_kw,
) -> FoldFits | None:
    """Identify ``model`` on each fold's rest of ``meas`` (at most ``folds`` folds; module
    docstring); None with fewer than 2 configurations (nothing to leave out). ``identify_kw``:
    further options of :func:`identify_tracker` (``sigma_d_m``, ``hold``), as the
    calibration's."""
    if meas.m < 2:
        return None
    config = configuration_index(meas.q, model.joint_types)
    count = int(config.max()) + 1
    if count < 2:
        return None
    k = min(count, folds)
    fold = fold_index(config, k)
    fits: dict[int, TrackerResult] = {}
    for f in range(k):
        train = meas.with_rows(fold != f)
        try:
            with warnings.catch_warnings():  # a fold's own rank notes: the whole fit has its own
                warnings.simplefilter("ignore")
                fits[f] = identify_tracker(
                    model, train, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad, **identify_kw
                )
        except EstimationError:
            continue
    return FoldFits(fold, k, count, fits)


@dataclass(frozen=True)
class CrossValidation:
    """K-fold held-out prediction errors (RMS over the rows of the folds that count).

    Attributes:
        rows: how many rows were predicted held out.
        folds, configurations: the folds and the distinct configurations they were dealt from.
        rms_mm, nominal_rms_mm: position error of the calibration and of the fair nominal (mm).
        rms_deg, nominal_rms_deg: rotation error (deg) for poses, else nan.
        failed: folds whose identification or fair nominal failed (too few rows left); their
            rows are not counted.
    """

    rows: int
    folds: int
    configurations: int
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
            "what": "k-fold cross-validation, one configuration (rows of the same joints) left "
            f"out at a time up to {MAX_FOLDS} folds: each fold's rows predicted by the "
            "calibration and by the fair nominal fitted to the other folds' rows",
            "rows": self.rows,
            "folds": self.folds,
            "configurations": self.configurations,
            "rms_mm": num(self.rms_mm),
            "nominal_rms_mm": num(self.nominal_rms_mm),
            "rms_deg": num(self.rms_deg),
            "nominal_rms_deg": num(self.nominal_rms_deg),
            "failed_folds": self.failed,
            "supported": self.supported,
        }

    @property
    def supported(self) -> bool:
        """Whether the calibration predicts the held-out rows better than the nominal (position,
        and rotation for poses)."""
        better = self.rms_mm < self.nominal_rms_mm
        if np.isfinite(self.rms_deg):
            better = better and self.rms_deg < self.nominal_rms_deg
        return bool(better)


def _rms(v: list[np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.square(np.concatenate(v))))) if v else float("nan")


def cross_validate(
    model: MCPCModel,
    meas: TrackerMeasurements,
    folds: FoldFits | None,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
) -> CrossValidation | None:
    """The held-out RMS of the calibration's fold fits ``folds`` (:func:`fit_folds` of ``model``
    on ``meas``) and of the fair nominal fitted to the same folds' rests (module docstring);
    None without folds or when no fold counts."""
    if folds is None:
        return None
    errs: dict[str, list[np.ndarray]] = {"pos": [], "rot": [], "npos": [], "nrot": []}
    for f, fit in sorted(folds.fits.items()):
        out = folds.fold == f
        try:
            nom = fit_nominal(model, meas.with_rows(~out), sigma_t_m=sigma_t_m,
                              sigma_r_rad=sigma_r_rad)  # fmt: skip
        except EstimationError:
            continue
        q, R = meas.q[out], None if meas.R is None else meas.R[out]
        for key, T in (("", fit.predict_poses(q)), ("n", nom.predict_poses(q))):
            pos, ang = pose_errors(T, meas.xyz[out], R)
            errs[key + "pos"].append(pos)
            if ang is not None:
                errs[key + "rot"].append(ang)
    if not errs["pos"]:
        return None
    return CrossValidation(
        rows=int(sum(len(v) for v in errs["pos"])),
        folds=folds.k,
        configurations=folds.configurations,
        rms_mm=_rms(errs["pos"]),
        nominal_rms_mm=_rms(errs["npos"]),
        rms_deg=_rms(errs["rot"]),
        nominal_rms_deg=_rms(errs["nrot"]),
        failed=folds.k - len(errs["pos"]),
    )


NO_GAIN = "NO GAIN: held out, the calibration's {what} error is no smaller than the fair nominal's"
"""The words of a calibration :attr:`CrossValidation.supported` says is no better (``what``:
position, orientation or both)."""


def _no_gain(block: dict) -> str:
    """:data:`NO_GAIN` naming what is not better in ``block`` (position and/or orientation)."""
    worse = [what for what, mine, nominal in (("position", "rms_mm", "nominal_rms_mm"),
                                              ("orientation", "rms_deg", "nominal_rms_deg"))
             if block.get(mine) is not None and block.get(nominal) is not None
             and not block[mine] < block[nominal]]  # fmt: skip
    return NO_GAIN.format(what=" and ".join(worse) or "position")


def cross_validation_line(block: dict | None) -> str | None:
    """The sentence of a ``calibration.json``'s ``fit.cross_validation`` block
    (:meth:`CrossValidation.to_json`; a file written before the k-fold check holds a
    leave-one-out block without ``folds``) that ``selfcal identify`` prints and report.md
    shows: the held-out RMS of the calibration beside the fair nominal's, and NO GAIN when the
    calibration is not better (:attr:`CrossValidation.supported`); None without a block."""
    if not block or block.get("rms_mm") is None or block.get("nominal_rms_mm") is None:
        return None

    def fig(key: str) -> str:
        deg = block.get(key.replace("_mm", "_deg"))
        return f"{block[key]:.4f} mm" + ("" if deg is None else f", {deg:.4f} deg")

    if block.get("folds") is None:
        how = f"leave-one-out over {block['rows']} rows"
    else:
        how = (f"cross-validated over {block['rows']} rows ({block['configurations']} "
               f"configurations in {block['folds']} folds)")  # fmt: skip
        if block.get("failed_folds"):
            how += f", {block['failed_folds']} folds not fitted (their rows not counted)"
    line = f"{how}: held-out RMS calibrated {fig('rms_mm')}; fair nominal {fig('nominal_rms_mm')}"
    return line if block.get("supported") else f"{line}; {_no_gain(block)}"
