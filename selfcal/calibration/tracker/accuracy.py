"""Predicted tool-point accuracy of a tracker calibration over the workspace (issue #29).

The estimation part is the identification's covariance (:class:`TrackerResult`, scaled by the
a-posteriori ``sigma0``) carried through the chain (:mod:`selfcal.kinematics.tool_error`). The
model-error part comes from held-out rows, so that a model that misfits is not judged by its
covariance alone: the rows are split into ``K = min(configurations, 10)`` folds, one
configuration (rows of the same joints) left out at a time up to 10 and the split independent of
the rows' order (:mod:`selfcal.calibration.tracker.cross_validation`, whose held-out RMS against
the fair nominal reads the same fits), each fold is predicted by the calibration fitted to the
others (the same options; distance rows stay in every fold), and the held-out squared error
is split as

    mean |r_i|^2 = mean tr S_fold(q_i) + 3 nu^2 + 3 m^2

with ``S_fold(q_i)`` the fold calibration's own predicted covariance of the tool point at the
row left out, ``nu`` the tracker's noise per coordinate (``sigma_t`` as given, times ``sigma0``
when that is below 1: a stated noise above what the fit shows is not subtracted) and ``m`` the
model error per coordinate, counted only when the excess over ``mean tr S + 3 nu^2`` is
significant (:data:`Z_MODEL_ERROR`). The same for the orientation of a fit of poses.
How it grows away from the calibration postures is read from the same rows
(:mod:`selfcal.calibration.growth`): each row's excess against its distance ``d`` from its
fold's training postures (each joint in units of its limits' range, a revolute joint's at most a
turn, its turns wrapped), ``m^2(d) = c0 + c1 d^2``, ``c1`` counted at its one-sided upper
confidence bound whether or not the rows show a growth
(``growth_shown``: above two standard errors), capped at what alone explains the rows' pooled
excess, ``c0`` the excess that leaves; ``m`` is then the size at the rows' mean distance and a
workspace point gets ``c0 + c1 d^2`` of its own distance from the calibration postures (the
orientation's model error, when there is one, grows the same way: its rows' pooled excess is
carried to the rows' mean distance by the position's variogram, not read from its own, which
would need its own growth in the block and ``ToolErrorModel``), held at its value at the
rows' largest distance beyond it, where it is not measured (the block says so,
``model_error.beyond_measured``).
What cannot be told apart: noise above the stated ``sigma_t`` is counted as model error (the
prediction is then pessimistic), a model error the postures cannot show (it repeats at every
row alike) is not counted.

The block :meth:`TrackerAccuracy.to_json` goes into ``calibration.json`` (``accuracy``); the
report rebuilds the prediction from it (:func:`error_model_from_json`). The split, the block and
its reading back are the routes' shared :mod:`selfcal.calibration.accuracy`. SI inside; ``_mm`` /
``_deg`` in the block.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration import accuracy as shared
from selfcal.calibration.accuracy import (
    SAMPLE_COUNT,
    Z_MODEL_ERROR,
    ModelError,
    model_error_of,
    spans_json,
    unmeasured_beyond,
)
from selfcal.calibration.accuracy import Accuracy as TrackerAccuracy
from selfcal.calibration.growth import fit_variogram
from selfcal.calibration.tracker.cross_validation import MAX_FOLDS, FoldFits, fit_folds
from selfcal.calibration.tracker.identify import TrackerResult
from selfcal.calibration.tracker.nominal import pose_errors
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.kinematics.tool_error import (
    EDGE_FRACTION,
    Reach,
    ToolErrorModel,
    joint_spans,
    posture_distance,
    revolute_joints,
    workspace_sample,
    workspace_summary,
)

__all__ = [
    "Z_MODEL_ERROR",
    "ModelError",
    "TrackerAccuracy",
    "model_error",
    "error_model",
    "tracker_accuracy",
    "error_model_from_json",
    "postures_from_json",
    "SAMPLE_COUNT",
]

WHAT = (
    "predicted error of the calibrated tool point (and tool orientation for a fit of poses) "
    "against the true one, in the tracker frame: the parameters' covariance carried through the "
    "chain plus a model error estimated from cross-validated rows (docs/tool-accuracy.md); "
    "95 % bounds of the error's norm per joint vector, summarised per region: inside = joint "
    "vectors within the calibration postures' joint ranges, edge = beyond them by up to "
    f"{EDGE_FRACTION:.0%} of each joint's range, workspace = within the joint limits"
)
NOTE = (
    "no cross-validation possible (fewer than 2 configurations of position / pose rows or "
    "every fold failed): "
    "the covariance alone, which is optimistic when the model misfits"
)


def error_model(
    res: TrackerResult, position_m: float, rotation_rad: float | None = None
) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of an identification (tracker frame) with the model error
    ``position_m`` / ``rotation_rad`` per coordinate."""
    cols = minimal_indices(res.model.joint_types)[res.estimated]
    return ToolErrorModel(res.model, res.T_meas_fit, cols, res.covariance, position_m,
                          rotation_rad)  # fmt: skip


def model_error(
    model: MCPCModel,
    meas: TrackerMeasurements,
    res: TrackerResult,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    folds: int = MAX_FOLDS,
    span: np.ndarray | None = None,
    fold_fits: FoldFits | None = None,
    **identify_kw,
) -> ModelError | None:
    """Cross-validate ``res`` (:func:`identify_tracker` of ``model`` on ``meas``) and estimate
    the model error (module docstring); None with fewer than 2 configurations of position /
    pose rows or when no fold could be fitted. ``folds``: at most this many folds; ``span`` (n,):
    the joints' spans (:func:`selfcal.kinematics.tool_error.joint_spans`) to read how the model
    error grows with a held-out row's distance from its fold's training postures
    (:mod:`selfcal.calibration.growth`), None: the same everywhere; ``fold_fits``: the folds'
    identifications when already fitted (:func:`fit_folds` with these options), else they are
    fitted here. ``identify_kw``: the identification's further options (``sigma_d_m``,
    ``hold``)."""
    if fold_fits is None:
        fold_fits = fit_folds(model, meas, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad,
                              folds=folds, **identify_kw)  # fmt: skip
    if fold_fits is None:
        return None
    k, failed, fold = fold_fits.k, fold_fits.failed, fold_fits.fold
    poses = meas.R is not None
    revolute = revolute_joints(model.joint_types)
    r2, r2_rot, s2, s2_rot, dist = [], [], [], [], []
    for f, fit in sorted(fold_fits.fits.items()):
        out = fold == f
        q = meas.q[out]
        R_out = None if meas.R is None else meas.R[out]
        pos, ang = pose_errors(fit.predict_poses(q), meas.xyz[out], R_out)
        S = error_model(fit, 0.0).estimation_covariance(q)
        r2.append(pos**2 / 1e6)
        s2.append(np.trace(S[:, :3, :3], axis1=1, axis2=2))
        if span is not None:
            dist.append(posture_distance(q, meas.q[~out], span, revolute))
        if ang is not None:
            r2_rot.append(np.radians(ang) ** 2)
            s2_rot.append(np.trace(S[:, 3:, 3:], axis1=1, axis2=2))
    if not r2:
        return None
    scale = min(1.0, res.sigma0)
    nu, nu_r = sigma_t_m * scale, sigma_r_rad * scale
    n2 = [np.full(len(v), 3.0 * nu**2) for v in r2]
    rot = (r2_rot, s2_rot, [np.full(len(v), 3.0 * nu_r**2) for v in r2_rot]) if poses else None
    me = model_error_of(r2, s2, n2, rot, folds=k - failed, failed=failed,
                        noise_what="the tracker noise")  # fmt: skip
    if me is None or me.position_m <= 0 or not dist:
        return me
    # how it grows: each row's excess over what the fold's estimate and the noise explain
    # (variance 2/3 (tr S + tr N)^2 without a model error), 3 c0 + 3 c1 d^2 (growth.py)
    e, d = np.concatenate(r2), np.concatenate(dist)
    expected = np.concatenate(s2) + np.concatenate(n2)
    gram = fit_variogram(
        e - expected, 2.0 / 3.0 * expected**2, np.full(e.size, 3.0), 3.0 * d**2, d, Z_MODEL_ERROR
    )
    reach = float(np.mean(d))
    if reach <= 0:
        return me
    # the orientation's excess is pooled over the same rows: carried to `reach` by the
    # position's variogram (the same shape assumed; growth.Variogram.carried)
    rot_m = None if me.rotation_rad is None else me.rotation_rad * np.sqrt(gram.carried(d, reach))
    return model_error_of(r2, s2, n2, rot, folds=k - failed, failed=failed,
                          noise_what="the tracker noise",
                          given=(float(np.sqrt(gram.at(reach))), rot_m),
                          reach_distance=reach, growth=gram,
                          measured_to=float(np.max(d)))  # fmt: skip


def tracker_accuracy(
    model: MCPCModel,
    meas: TrackerMeasurements,
    res: TrackerResult,
    limits: np.ndarray,
    *,
    sigma_t_m: float,
    sigma_r_rad: float,
    count: int = SAMPLE_COUNT,
    fold_fits: FoldFits | None = None,
    **identify_kw,
) -> TrackerAccuracy | None:
    """The predicted accuracy of ``res`` (:func:`identify_tracker` of ``model`` on ``meas``)
    at the calibration postures and over ``count`` joint vectors per region within ``limits``
    (n, 2) rad / m; None without position / pose rows (distances do not place the tracker
    frame). ``fold_fits``: the cross-validation folds' identifications when already fitted
    (:func:`fit_folds`), else the model error fits them."""
    if meas.m == 0:
        return None
    span = joint_spans(limits, revolute_joints(model.joint_types))
    me = model_error(model, meas, res, sigma_t_m=sigma_t_m, sigma_r_rad=sigma_r_rad, span=span,
                     fold_fits=fold_fits, **identify_kw)  # fmt: skip
    pos = 0.0 if me is None else me.position_m
    rot = None if meas.R is None else (0.0 if me is None else me.rotation_rad)
    em = error_model(res, pos, rot)
    if me is not None and me.reach_distance > 0 and span is not None:
        em = em.with_reach(Reach(meas.q, span, me.reach_distance, me.reach_floor,
                                 unmeasured_beyond(me)))  # fmt: skip
    sample = workspace_sample(meas.q, limits, count=count)
    names = tuple(n for n, e in zip(res.names, res.estimated) if e)
    summary = workspace_summary(em, sample, meas.q)
    return TrackerAccuracy(em, names, me, summary, sample, np.array(meas.q, dtype=float),
                           WHAT, NOTE, {"joint_limits_si": np.asarray(limits, float).tolist(),
                                       **spans_json(span)})  # fmt: skip


_FIX = "re-run `selfcal identify` to write the block again"


def error_model_from_json(block: dict, model: MCPCModel, T_meas_fit: np.ndarray,
                          names: tuple[str, ...], poses: bool, where: str) -> ToolErrorModel:  # fmt: skip
    """The :class:`ToolErrorModel` of a tracker calibration file's ``accuracy`` block
    (``names``: the file's minimal parameter names, ``poses``: whether the fit used poses).

    Raises:
        InputError: the block's parameters are not the file's or its covariance is malformed.
    """
    return shared.error_model_from_json(block, model, T_meas_fit, names, poses, where, fix=_FIX)


def postures_from_json(block: dict, n: int, where: str) -> np.ndarray:
    """The calibration postures (m, n) rad / m of an ``accuracy`` block.

    Raises:
        InputError: missing or malformed.
    """
    return shared.postures_from_json(block, n, where, fix=_FIX)
