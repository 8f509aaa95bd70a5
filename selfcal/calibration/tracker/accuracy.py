"""Predicted tool-point accuracy of a tracker calibration over the workspace (issue #29).

The estimation part is the identification's covariance (:class:`TrackerResult`, scaled by the
a-posteriori ``sigma0``) carried through the chain (:mod:`selfcal.kinematics.tool_error`). The
model-error part comes from held-out rows, so that a model that misfits is not judged by its
covariance alone: the rows are split into ``K = min(m, 10)`` folds (by the order of their joint
vectors, so the input order does not matter), each fold is predicted by the calibration fitted to
the others (the same options; distance rows stay in every fold), and the held-out squared error
is split as

    mean |r_i|^2 = mean tr S_fold(q_i) + 3 nu^2 + 3 m^2

with ``S_fold(q_i)`` the fold calibration's own predicted covariance of the tool point at the
row left out, ``nu`` the tracker's noise per coordinate (``sigma_t`` as given, times ``sigma0``
when that is below 1: a stated noise above what the fit shows is not subtracted) and ``m`` the
model error per coordinate, counted only when the excess over ``mean tr S + 3 nu^2`` is
significant (:data:`Z_MODEL_ERROR`). The same for the orientation of a fit of poses.
What cannot be told apart: noise above the stated ``sigma_t`` is counted as model error (the
prediction is then pessimistic), a model error the postures cannot show (it repeats at every
row alike) is not counted.

The block :meth:`TrackerAccuracy.to_json` goes into ``calibration.json`` (``accuracy``); the
report rebuilds the prediction from it (:func:`error_model_from_json`). SI inside; ``_mm`` /
``_deg`` in the block.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.tracker.identify import TrackerResult, identify_tracker
from selfcal.calibration.tracker.nominal import pose_errors
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.kinematics.tool_error import (
    EDGE_FRACTION,
    ToolErrorModel,
    WorkspaceSample,
    workspace_sample,
    workspace_summary,
)

__all__ = [
    "MAX_FOLDS",
    "Z_MODEL_ERROR",
    "ModelError",
    "TrackerAccuracy",
    "fold_index",
    "model_error",
    "error_model",
    "tracker_accuracy",
    "error_model_from_json",
    "postures_from_json",
    "SAMPLE_COUNT",
]

SAMPLE_COUNT = 256
"""Joint vectors per region of the workspace sample."""

Z_MODEL_ERROR = 2.0
"""A model error is counted when the held-out errors exceed what the estimation error and the
noise explain by more than this many standard errors (one-sided, ~2 %): an excess of that size
arises by chance in 1 calibration in 40 that has no model error; below it the estimate would
be mostly the sampling noise of the held-out errors, which clipped at 0 inflates the
prediction."""

MAX_FOLDS = 10
"""At most this many cross-validation folds (one identification each)."""

WHAT = (
    "predicted error of the calibrated tool point (and tool orientation for a fit of poses) "
    "against the true one, in the tracker frame: the parameters' covariance carried through the "
    "chain plus a model error estimated from cross-validated rows (docs/tool-accuracy.md); "
    "95 % bounds of the error's norm per joint vector, summarised per region: inside = joint "
    "vectors within the calibration postures' joint ranges, edge = beyond them by up to "
    f"{EDGE_FRACTION:.0%} of each joint's range, workspace = within the joint limits"
)


def fold_index(q: np.ndarray, k: int) -> np.ndarray:
    """(m,) fold of each row of ``q`` (m, n): rows sorted by their joint vectors
    (lexicographically) are dealt to ``k`` folds in turn, so the split does not depend on the
    rows' order in the file."""
    order = np.lexsort(np.asarray(q, dtype=float).T[::-1])
    fold = np.empty(len(order), int)
    fold[order] = np.arange(len(order)) % k
    return fold


@dataclass(frozen=True)
class ModelError:
    """The model error estimated from held-out rows (module docstring); SI.

    Attributes:
        position_m, rotation_rad: per-coordinate standard deviations (rotation: None without
            poses).
        folds, rows, failed: folds used, rows predicted, folds whose fit failed.
        held_out_rms_m, held_out_rms_rad: RMS of the held-out errors' norms (rad: nan without
            poses); estimation_rms_m, estimation_rms_rad: what the folds' covariances explain
            (``sqrt(mean tr S)``); noise_m, noise_rad: the tracker noise per coordinate taken out.
    """

    position_m: float
    rotation_rad: float | None
    folds: int
    rows: int
    failed: int
    held_out_rms_m: float
    held_out_rms_rad: float
    estimation_rms_m: float
    estimation_rms_rad: float
    noise_m: float
    noise_rad: float

    def to_json(self) -> dict:
        def num(x: float | None, k: float) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x * k)

        deg = 180.0 / np.pi
        return {
            "what": "per-coordinate standard deviation of what the model cannot express, from "
            "the cross-validated rows' errors less the folds' predicted estimation error and the "
            "tracker noise",
            "position_mm": num(self.position_m, 1e3),
            "rotation_deg": num(self.rotation_rad, deg),
            "folds": self.folds,
            "rows": self.rows,
            "failed_folds": self.failed,
            "held_out_rms_mm": num(self.held_out_rms_m, 1e3),
            "held_out_rms_deg": num(self.held_out_rms_rad, deg),
            "estimation_rms_mm": num(self.estimation_rms_m, 1e3),
            "estimation_rms_deg": num(self.estimation_rms_rad, deg),
            "noise_mm": num(self.noise_m, 1e3),
            "noise_deg": num(self.noise_rad, deg),
        }


def error_model(
    res: TrackerResult, position_m: float, rotation_rad: float | None = None
) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of an identification (tracker frame) with the model error
    ``position_m`` / ``rotation_rad`` per coordinate."""
    cols = minimal_indices(res.model.joint_types)[res.estimated]
    return ToolErrorModel(res.model, res.T_meas_fit, cols, res.covariance, position_m,
                          rotation_rad)  # fmt: skip


def _excess(total2: float, explained2: float, noise: float, rows: int) -> float:
    """Per-coordinate standard deviation of what ``total2`` (the mean squared norm over ``rows``
    held-out rows) leaves beyond ``explained2`` and three coordinates of ``noise``; 0 unless
    that excess exceeds :data:`Z_MODEL_ERROR` standard errors of ``total2`` under no model error
    (a squared norm of three Gaussian coordinates has variance 2/3 of its square mean)."""
    expected = explained2 + 3.0 * noise**2
    excess = total2 - expected
    if excess <= Z_MODEL_ERROR * expected * np.sqrt(2.0 / (3.0 * rows)):
        return 0.0
    return float(np.sqrt(excess / 3.0))


def model_error(
    model: MCPCModel,
    meas: TrackerMeasurements,
    res: TrackerResult,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    folds: int = MAX_FOLDS,
    **identify_kw,
) -> ModelError | None:
    """Cross-validate ``res`` (:func:`identify_tracker` of ``model`` on ``meas``) and estimate
    the model error (module docstring); None without position / pose rows or when no fold could
    be fitted. ``identify_kw``: the identification's further options (``sigma_d_m``, ``hold``)."""
    if meas.m < 2:
        return None
    k = min(meas.m, folds)
    fold = fold_index(meas.q, k)
    poses = meas.R is not None
    r2, r2_rot, s2, s2_rot = [], [], [], []
    failed = 0
    for f in range(k):
        out = fold == f
        train = meas.with_rows(~out)
        try:
            with warnings.catch_warnings():  # a fold's own rank notes: the whole fit has its own
                warnings.simplefilter("ignore")
                fit = identify_tracker(
                    model, train, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad, **identify_kw
                )
        except EstimationError:
            failed += 1
            continue
        q = meas.q[out]
        R_out = None if meas.R is None else meas.R[out]
        pos, ang = pose_errors(fit.predict_poses(q), meas.xyz[out], R_out)
        S = error_model(fit, 0.0).estimation_covariance(q)
        r2.append(pos**2 / 1e6)
        s2.append(np.trace(S[:, :3, :3], axis1=1, axis2=2))
        if ang is not None:
            r2_rot.append(np.radians(ang) ** 2)
            s2_rot.append(np.trace(S[:, 3:, 3:], axis1=1, axis2=2))
    if not r2:
        return None
    scale = min(1.0, res.sigma0)
    nu, nu_r = sigma_t_m * scale, sigma_r_rad * scale
    n_rows = int(sum(len(v) for v in r2))
    e2, es2 = float(np.mean(np.concatenate(r2))), float(np.mean(np.concatenate(s2)))
    rot = None
    e2r = es2r = float("nan")
    if poses:
        e2r, es2r = float(np.mean(np.concatenate(r2_rot))), float(np.mean(np.concatenate(s2_rot)))
        rot = _excess(e2r, es2r, nu_r, n_rows)
    return ModelError(
        position_m=_excess(e2, es2, nu, n_rows),
        rotation_rad=rot,
        folds=k - failed,
        rows=n_rows,
        failed=failed,
        held_out_rms_m=float(np.sqrt(e2)),
        held_out_rms_rad=float(np.sqrt(e2r)),
        estimation_rms_m=float(np.sqrt(es2)),
        estimation_rms_rad=float(np.sqrt(es2r)),
        noise_m=nu,
        noise_rad=nu_r if poses else float("nan"),
    )


@dataclass(frozen=True)
class TrackerAccuracy:
    """The predicted accuracy of a tracker calibration (module docstring): its error model, the
    estimated parameters' ``names``, the model-error estimate, the summary over the workspace
    (:func:`selfcal.kinematics.tool_error.workspace_summary`) of ``sample`` and the calibration
    postures ``q_cal`` (m, n) rad / m."""

    error_model: ToolErrorModel
    names: tuple[str, ...]
    model_error: ModelError | None
    summary: dict
    sample: WorkspaceSample
    q_cal: np.ndarray

    def to_json(self) -> dict:
        """The ``accuracy`` block of ``calibration.json`` (units in the key names)."""
        em = self.error_model
        return {
            "what": WHAT,
            "units": "mm and deg; covariance SI (rad, m) in the order of `estimated`",
            "model_error": None if self.model_error is None else self.model_error.to_json(),
            "model_error_note": None
            if self.model_error is not None
            else "no cross-validation possible (fewer than 2 position / pose rows or every fold "
            "failed): the covariance alone, which is optimistic when the model misfits",
            "calibrated_region_si": self.sample.box.tolist(),
            "calibration_postures_si": self.q_cal.tolist(),
            "regions": self.summary,
            "estimated": list(self.names),
            "covariance_si": em.covariance.tolist(),
        }


def tracker_accuracy(
    model: MCPCModel,
    meas: TrackerMeasurements,
    res: TrackerResult,
    limits: np.ndarray,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    count: int = SAMPLE_COUNT,
    **identify_kw,
) -> TrackerAccuracy | None:
    """The predicted accuracy of ``res`` (:func:`identify_tracker` of ``model`` on ``meas``)
    at the calibration postures and over ``count`` joint vectors per region within ``limits``
    (n, 2) rad / m; None without position / pose rows (distances do not place the tracker
    frame)."""
    if meas.m == 0:
        return None
    me = model_error(model, meas, res, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad,
                     **identify_kw)  # fmt: skip
    pos = 0.0 if me is None else me.position_m
    rot = None if meas.R is None else (0.0 if me is None else me.rotation_rad)
    em = error_model(res, pos, rot)
    sample = workspace_sample(meas.q, limits, count=count)
    names = tuple(n for n, e in zip(res.names, res.estimated) if e)
    summary = workspace_summary(em, sample, meas.q)
    return TrackerAccuracy(em, names, me, summary, sample, np.array(meas.q, dtype=float))


def error_model_from_json(block: dict, model: MCPCModel, T_meas_fit: np.ndarray,
                          names: tuple[str, ...], poses: bool, where: str) -> ToolErrorModel:  # fmt: skip
    """The :class:`ToolErrorModel` of a calibration file's ``accuracy`` block (``names``: the
    file's minimal parameter names, ``poses``: whether the fit used poses).

    Raises:
        InputError: the block's parameters are not the file's or its covariance is malformed.
    """
    est = tuple(block.get("estimated", ()))
    unknown = [n for n in est if n not in names]
    cov = np.asarray(block.get("covariance_si", []), dtype=float)
    fix = "re-run `selfcal identify` to write the block again"
    if unknown or cov.shape != (len(est), len(est)) or not np.all(np.isfinite(cov)):
        raise InputError(f"{where}: the accuracy block's covariance does not match its "
                         f"parameters {list(est)}", fix=fix)  # fmt: skip
    idx = minimal_indices(model.joint_types)
    cols = idx[[names.index(n) for n in est]]
    me = block.get("model_error") or {}
    pos = (me.get("position_mm") or 0.0) / 1e3
    rot = np.radians(me.get("rotation_deg") or 0.0) if poses else None
    return ToolErrorModel(model, np.asarray(T_meas_fit, float), cols, cov, pos, rot)


def postures_from_json(block: dict, n: int, where: str) -> np.ndarray:
    """The calibration postures (m, n) rad / m of an ``accuracy`` block.

    Raises:
        InputError: missing or malformed.
    """
    q = np.asarray(block.get("calibration_postures_si", []), dtype=float)
    if q.ndim != 2 or q.shape[1] != n or len(q) == 0 or not np.all(np.isfinite(q)):
        raise InputError(f"{where}: accuracy.calibration_postures_si must be m rows of {n} "
                         "joint values", fix="re-run `selfcal identify` to write the block again")  # fmt: skip
    return q
