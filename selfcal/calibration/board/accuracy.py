"""Predicted tool-point accuracy of a board calibration over the workspace (issue #29).

The tool point is the flange (the robot file's flange -> camera mount seen from the camera;
eye-to-hand the calibrated flange -> board mount seen from the board), predicted in the chain's
world frame: the board frame (eye-to-hand: the first camera's frame). Its error has the two
parts of :mod:`selfcal.calibration.accuracy`:

- the estimation error: the Cramer-Rao covariance of the estimated minimal parameters at the
  estimate with the fit's own pixel noise (:mod:`selfcal.calibration.board.bounds`: the cameras,
  the joint read-back corrections and, for a rig, the extrinsics marginalised) carried through
  the chain (:class:`selfcal.kinematics.tool_error.ToolErrorModel`);
- the model error, from the parameter selection's own leave-one-configuration-out folds
  (:mod:`selfcal.calibration.board.param_selection`: the chosen candidate fitted without each
  fold): every held-out frame's first-camera pixels, predicted from its joints alone, against
  the detected ones. What the fold's errors (its Cramer-Rao covariance of the kinematics and the
  first camera, with their correlation), the joint read-back noise and the pixel noise give
  their squared sum is carried to the pixels (:func:`held_out_errors`); the excess beyond
  :data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` standard errors (``2 tr Sigma^2`` per
  frame) that no share of the held parameters' one deviation explains across the folds
  (:mod:`selfcal.calibration.board.held_null`) is a model error ``m`` per tool-point coordinate and ``m / L`` per rotation coordinate
  (``L`` the tool point's mean distance to the board points in view: the rotation then moves
  the view about as much as the translation) whose pixel effect is that excess: in the held-out
  frame itself and through what the same error in the fold's training frames did to its
  estimate (:mod:`selfcal.calibration.board.misfit`: a fold that extrapolates is thrown far by
  it, and is not read as a large model error everywhere). The calibration's covariance gets
  the same (``m^2 G`` of its own frames) in its prediction. The model error is taken as a
  smooth function of the joints that the fit matched at the postures it saw: its variance at the
  distance ``d`` (each joint in units of its limits' range, a revolute joint's at most a turn:
  :func:`joint_spans`) from the nearest is ``c0 + c1 d^2``,
  read from each held-out frame's excess at its own distance from its fold's training postures
  (:func:`grown_size`, :mod:`selfcal.calibration.growth`: ``c1`` at its 95 % upper bound); ``m``
  is the size at their mean distance (:attr:`ModelError.reach_distance`) and a workspace point
  gets ``c0 + c1 d^2``, held beyond the held-out frames' largest distance
  (:class:`selfcal.kinematics.tool_error.ToolErrorModel`). Each held-out
  frame's tool-point error as the pose correction that fits its pixels best (linear least
  squares on the projection's Jacobian, ``B xi``) is kept beside it
  (:class:`selfcal.calibration.accuracy.ModelError`'s held-out RMS): a single view knows it
  poorly along its line of sight, so the model error is not taken from it; its excess with each
  frame in its own metric (``whitened_excess_mm`` / ``_deg``,
  :func:`selfcal.calibration.whitened.whitened_excess`) is the drift check's second null
  (:mod:`selfcal.calibration.drift.fold_error`).

The parameters the selection held at the drawing: their deviation, less what the fit absorbs
of it, is in the covariance too, scaled to the share of the prior (``deviation``) that the
folds' excess shows, counted at its upper 95 % confidence bound from the folds' spread (the
prior unscaled without folds); the model error is what the folds leave beyond the share's
point estimate (:mod:`selfcal.calibration.board.held`,
:mod:`selfcal.calibration.board.held_prior`).

What this cannot see: a model error the same in every frame is absorbed by the placement (board
pose, hand-eye) and is not seen; how fast a misfit grows is read only out to the held-out
frames' largest distance from their training postures (``measured_to_distance``: beyond it the
model error is held at its value there and the block says it is not measured; so too when the
folds found none: no fold tested the model there); the power of the
growth (2 for the variance) is assumed; a misfit
the folds do not show (below two standard errors) is not counted anywhere, however it would grow;
held-out configurations far outside the others (few configurations) make the folds'
extrapolation, not the calibration's, the measure.

The folds read here are the ones that count in the selection
(:func:`selfcal.calibration.board.folds.counted_folds`, :meth:`Selection.counts`): a fold that
leaves out more than half of the frames is fitted on a smaller experiment than the calibration,
so its error at the frames it left out is neither the calibration's model error nor its held-out
error; the model error, the held share and the held-out RMS leave it out as the selection does
(the jackknife, :mod:`selfcal.calibration.board.spread`, takes every fold: it says why).

Beside it, the cross-validated reprojection (``accuracy.cross_validation``): every counted fold's
held-out frames predicted by the chosen candidate and by the fair nominal (the first candidate,
:mod:`selfcal.calibration.board.nominal_fit`'s objective on the same training frames), as the
2-D RMS in px and in mm at the board (the detected pixel's ray met with the board's plane at the
predicted pose, against the predicted corner). Nothing here reads truth.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from selfcal.calibration.accuracy import (
    SAMPLE_COUNT,
    Z_MODEL_ERROR,
    Accuracy,
    ModelError,
    error_model_from_json,
    model_error_of,
    postures_from_json,
    spans_json,
    unmeasured_beyond,
)
from selfcal.calibration.board.bounds import BoardCramerRao
from selfcal.calibration.board.covariances import (
    bounds_covariance,
    bounds_noise_covariance,
    padded_bounds_covariance,
)
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.fold_fits import fold_bounds
from selfcal.calibration.board.held_null import (
    counted_excess,
    fold_noise_variance,
    shared_covariances,
)
from selfcal.calibration.board.held_prior import (
    NO_FOLDS,
    Share,
    held_block,
    held_share,
    with_deviation,
)
from selfcal.calibration.board.misfit import board_view, pose_jacobian, tip_map, unit_rows
from selfcal.calibration.board.param_selection import Selection
from selfcal.calibration.board.refine import BoardObservations, Refinement, predicted_points
from selfcal.calibration.growth import Variogram, fit_variogram
from selfcal.calibration.whitened import whitened_rows, with_whitened
from selfcal.camera import CameraModel
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
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
from selfcal.solver.covariance import psd_sqrt

__all__ = [
    "ORIENTATION",
    "POSITION",
    "board_accuracy",
    "board_error_model",
    "board_error_model_from_json",
    "board_postures_from_json",
    "cross_validated_reprojection",
    "grown_size",
    "held_out_errors",
    "joint_spans",
    "model_error",
    "pose_error_terms",
    "predicted_reprojection",
]

_FIX = "re-run `selfcal calibrate` to write the block again"


def _what(eye_to_hand: bool, tool_point: str) -> str:
    frame = "the first camera's frame" if eye_to_hand else "the board frame"
    return (
        f"predicted error of the calibrated tool point ({tool_point}) and tool orientation against "
        f"the true ones, in {frame}: the Cramer-Rao covariance at the estimate carried through "
        "the chain, with the share of the held parameters' deviation from the drawing the folds "
        "show at its upper 95 % confidence bound (held_deviation), plus a model error estimated from the leave-one-configuration-out folds "
        "(docs/tool-accuracy.md); 95 % bounds of the error's norm per joint vector, summarised "
        "per region: inside = joint vectors within the calibration postures' joint ranges, edge "
        f"= beyond them by up to {EDGE_FRACTION:.0%} of each joint's range, workspace = within "
        "the joint limits"
    )


def board_error_model(cr: BoardCramerRao, T_tool_point: np.ndarray, position_m: float = 0.0,
                      rotation_rad: float = 0.0, reach: Reach | None = None,
                      ) -> tuple[ToolErrorModel, tuple[str, ...]]:  # fmt: skip
    """The :class:`ToolErrorModel` of the bounds ``cr`` (world = the chain's, the tool point
    ``T_tool_point`` in the chain's tool frame) with the model error ``position_m`` /
    ``rotation_rad`` per coordinate, and the names of the parameters its covariance covers (the
    minimal parameters the estimate moved); ``reach``: where the model error grows from
    (:class:`Reach`), None: the same everywhere; the covariance is the Cramer-Rao one plus what the
    model error in the calibration's frames gives the estimate (``position_m^2 G``,
    :mod:`selfcal.calibration.board.misfit`)."""
    idx = minimal_indices(cr.model.joint_types)
    est = np.ones(idx.size, bool) if cr.estimated is None else np.asarray(cr.estimated, bool)
    p = int(est.sum())
    cov = cr.covariance[np.ix_(est, est)] + position_m**2 * bounds_covariance(cr, True)[1][:p, :p]
    em = ToolErrorModel(cr.model, np.eye(4), idx[est], cov, position_m, rotation_rad,
                        np.asarray(T_tool_point, float))  # fmt: skip
    em = em.with_reach(reach)
    return em, tuple(param_names(idx[est]))


def held_out_errors(obs: BoardObservations, fit: Refinement, frames: np.ndarray,
                    T_tool_point: np.ndarray, cr: BoardCramerRao) -> dict[str, np.ndarray]:  # fmt: skip
    """For every frame of ``frames`` (m,) bool with first-camera rows, ``fit``'s prediction from
    the joints alone against the detected pixels (module docstring), ``cr`` its bounds (its
    covariance and the pixel noise). By key, one entry per frame: ``frame``; ``px2`` the sum of
    its squared pixel errors, ``px2_expected`` what the estimate's errors (kinematics and first
    camera, with their correlation), the joint read-back noise and the pixel noise give it,
    ``px2_var`` that sum's variance without a model error (``2 tr Sigma^2``), ``px2_cov`` its
    covariance with the other frames' sums (``fit``'s one estimate error predicts them all:
    ``2 sum_j tr(U_i^T U_i U_j^T U_j)``, :func:`selfcal.calibration.board.held_null.shared_covariances`;
    a fold's sum has the variance ``sum px2_var + sum px2_cov``), ``px2_unit`` what
    a model error of 1 m per tool-point coordinate (and 1 m / lever rad per rotation coordinate)
    in this frame adds to it, ``px2_misfit`` what the same in the training frames adds through
    the estimate (:mod:`selfcal.calibration.board.misfit`); ``held_gram`` (k, k) ``L^T L``,
    ``L`` the frame's pixels per unit deviation of each minimal parameter from the drawing
    (through ``cr``'s held response, the fit's absorption included; zero when ``cr`` carries
    none): its deviation ``delta`` adds ``|L delta|^2`` to ``px2``, ``held_cross`` (k,) the
    diagonal of ``L^T Sigma L`` (``Sigma`` the pixels' covariance of ``px2_var``: the
    deviation's cross term with the noise; :mod:`selfcal.calibration.board.held_null`) plus its
    covariance with the other frames' through the shared estimate error (summed over the frames,
    the diagonal of the stacked frames' ``L^T Sigma L``); ``lever`` the tool point's mean
    distance (m) to the board points in view; the flange's error as the best pose correction of the pixels ``e`` (6,) (position m, orientation
    rad, world frame) with the covariances the estimate's errors ``S`` (6, 6) and the noise
    ``N`` (6, 6) give it, ``G`` (6, k + c) what an error of the estimate gives it (``S = G C
    G^T``), ``C`` (k + c, k + c) that covariance (the same for every frame of ``fit``) and ``A``
    (k + c, k + c) the information the frame's first-camera pixels (under the pixel and joint
    read-back noise) give an estimate, all in every minimal parameter's order (zero where ``cr``
    holds one) then the first camera's free parameters: :func:`whitened_rows`."""
    cam, v, Xc, uv, _ = predicted_points(obs, fit, frames)[0]
    t = np.asarray(T_tool_point, float)[:3, 3]
    js = obs.joint_sigma
    cols, C, n0 = bounds_covariance(cr)
    C_half = psd_sqrt(C)
    G_half = psd_sqrt(bounds_covariance(cr, misfit=True)[1])
    s2 = cr.pixel_sigma_px**2
    keys = ("frame", "px2", "px2_expected", "px2_var", "px2_cov", "px2_unit", "px2_misfit", "held_gram",
            "held_cross", "lever", "e", "S", "N", "G", "C", "A")  # fmt: skip
    idx = minimal_indices(cr.model.joint_types)
    C_all = padded_bounds_covariance(cr)
    held = np.zeros((len(C_all), idx.size)) if cr.held is None else cr.held
    out: dict[str, list] = {k: [] for k in keys}
    shared: list[np.ndarray] = []  # per frame the fit's estimate error at its pixels (rows, p)
    held_px: list[np.ndarray] = []  # per frame its pixels per unit held deviation (rows, k)
    for i in np.unique(v).tolist():
        rows = v == i
        T = fk_tool(cr.model, obs.q[i][None])[0]
        x = Xc[rows]
        uv_hat, Jx, Jc = cam.project_free(x)  # px, px per m (k, 2, 3), px per parameter
        r = (uv_hat - uv[rows]).reshape(-1)
        A = pose_jacobian(Jx, x, T, obs.eye_to_hand)
        AtA_inv = np.linalg.inv(A.T @ A)
        B = tip_map(T, t)
        J = identification_jacobian(cr.model, obs.q[i][None])[0]
        H = np.concatenate([A @ J[:, cols], Jc.reshape(-1, n0)], axis=1)
        H_all = np.concatenate([A @ J[:, idx], Jc.reshape(-1, n0)], axis=1)
        U = H @ C_half  # the estimate's pixel errors: U U^T
        shared.append(U)
        P = AtA_inv @ A.T  # pixels -> the pose correction (body twist)
        N = s2 * B @ AtA_inv @ B.T
        info = H_all.T @ H_all / s2  # the frame's information on the estimate (Woodbury)
        if js is not None:
            tw = joint_twists(cr.model, obs.q[i][None])[0]  # (6, n) body twists
            Q = tw * np.broadcast_to(np.asarray(js, float), (tw.shape[1],))
            U = np.concatenate([U, A @ Q], axis=1)
            N = N + B @ Q @ Q.T @ B.T
            HU = H_all.T @ (A @ Q)
            info -= HU @ np.linalg.solve(s2 * np.eye(Q.shape[1]) + (A @ Q).T @ (A @ Q), HU.T) / s2
        K, lever = unit_rows(A, x, T, t, obs.eye_to_hand)
        UtU = U.T @ U
        L = H_all @ held  # the pixels per unit deviation of each minimal parameter
        held_px.append(L)
        vals = {
            "frame": i,
            "px2": float(r @ r),
            "px2_expected": float(np.trace(UtU)) + r.size * s2,
            "px2_var": 2.0
            * (
                float(np.sum(UtU * UtU)) + 2 * s2 * float(np.trace(UtU)) + r.size * s2**2
            ),  # fmt: skip
            "px2_cov": 0.0,  # below, from every frame's shared estimate error
            "px2_unit": float(np.sum(K**2)),
            "px2_misfit": float(np.sum((H @ G_half) ** 2)),
            "held_gram": L.T @ L,
            "held_cross": np.sum((U.T @ L) ** 2, axis=0) + s2 * np.sum(L**2, axis=0),
            "lever": lever,
            "e": -B @ P @ r,
            "S": B @ P @ (H @ C @ H.T) @ P.T @ B.T,
            "N": N,
            "G": B @ P @ H_all,
            "C": C_all,
            "A": info,
        }
        for k in keys:
            out[k].append(vals[k])
    if shared:  # the frames' covariances through the fit's one estimate error
        cov, cross = shared_covariances(shared, held_px)
        out["px2_cov"] = list(cov)
        out["held_cross"] = [a + b for a, b in zip(out["held_cross"], cross, strict=True)]
    return {k: np.array(val) for k, val in out.items()}


def grown_size(excess: np.ndarray, var: np.ndarray, unit: np.ndarray, misfit: np.ndarray,
               distance: np.ndarray) -> tuple[float, float, Variogram | None]:  # fmt: skip
    """The model error's size ``m`` (m per tool-point coordinate) at the distance ``reach``
    and how it grows (:class:`selfcal.calibration.growth.Variogram`, None without distances),
    from the held-out frames' squared-pixel excess ``excess`` (px^2, per frame), its variance
    without a model error ``var`` (px^4), what a unit model error adds to it in the frame
    itself ``unit`` (``u``, px^2 per m^2), through the fold's estimate ``misfit`` (``w``) and
    the frame's distance to its fold's training postures ``distance``
    (:func:`posture_distance`).

    A frame at ``d`` has the variance ``c0 + c1 d^2`` in itself; the training frames' share
    (``w``) is taken at ``reach``, the frames' mean distance, as the calibration's own
    covariance takes it: ``excess_i ~ c0 (u_i + w_i) + c1 (u_i d_i^2 + w_i reach^2)``
    (:func:`selfcal.calibration.growth.fit_variogram`: ``c1`` at its upper confidence bound).
    ``m^2 = c0 + c1 reach^2``; with every distance 0 (no spans) the same everywhere,
    ``m^2 = sum excess / (sum u + sum w)`` and ``reach`` 0."""
    y, v, u, w, d = (np.asarray(x, dtype=float) for x in (excess, var, unit, misfit, distance))
    reach = float(np.mean(d)) if d.size else 0.0
    if reach <= 0:
        return float(np.sqrt(max(np.sum(y), 0.0) / (np.sum(u) + np.sum(w)))), 0.0, None
    gram = fit_variogram(y, v, u + w, u * d**2 + w * reach**2, d, Z_MODEL_ERROR)
    return float(np.sqrt(gram.at(reach))), reach, gram


POSITION, ORIENTATION = slice(0, 3), slice(3, 6)
"""The flange error's coordinates (position, orientation) in :func:`held_out_errors`."""


def pose_error_terms(h: dict, b: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame of :func:`held_out_errors`' ``h``, its flange error's coordinates ``b``
    (:data:`POSITION`, m; :data:`ORIENTATION`, rad): squared norm, traces of ``S`` and ``N``
    (``r2``, ``s2``, ``n2`` of :func:`selfcal.calibration.accuracy.model_error_of`)."""
    e, S, N = h["e"][:, b], h["S"][:, b, b], h["N"][:, b, b]
    return np.sum(e**2, axis=1), np.trace(S, axis1=1, axis2=2), np.trace(N, axis1=1, axis2=2)


def model_error(obs: BoardObservations, selection: Selection, offsets: np.ndarray,
                T_tool_point: np.ndarray, pixel_sigma_px: float,
                variance: np.ndarray | None = None,
                span: np.ndarray | None = None) -> tuple[ModelError | None, Share]:  # fmt: skip
    """The model error (module docstring) from the chosen candidate's fold fits that count
    (:func:`selfcal.calibration.board.fold_fits.fold_bounds`; None without folds, one
    configuration, or when no counted fold was fitted) and the share of the deviation
    ``variance`` (k,) from the drawing (:func:`selfcal.calibration.board.held_prior.held_share`)
    the folds' excess shows (the prior unscaled without folds); the model error is what is left
    beyond its point estimate. ``span`` (n,): the joints' spans (:func:`joint_spans`) when the
    model error grows with the distance from the calibration postures (module docstring): each
    held-out frame's excess is then read at its distance to its fold's training postures
    (:func:`grown_size`), the error's size ``m`` is the one at their mean distance
    (:attr:`ModelError.reach_distance`); the held-out frames' largest distance is how far the
    folds tested the model (:attr:`ModelError.measured_to`), found or not."""
    got = []
    for out, fit, cr in fold_bounds(obs, selection, offsets, T_tool_point, pixel_sigma_px):
        train = obs.used & ~out
        h = held_out_errors(obs, fit, out, T_tool_point, cr)
        h["px2_held"] = np.zeros(len(h["frame"]))
        h["S_held"] = np.zeros_like(h["S"])
        h["distance"] = (np.zeros(len(h["frame"])) if span is None else
                         posture_distance(obs.q[h["frame"].astype(int)], obs.q[train], span,
                                          revolute_joints(cr.model.joint_types)))  # fmt: skip
        if variance is not None and len(h["frame"]):
            dev = held_out_errors(obs, fit, out, T_tool_point, with_deviation(cr, variance))
            h["px2_held"] = dev["px2_expected"] - h["px2_expected"]
            h["S_held"] = dev["S"] - h["S"]  # the deviation's at the held-out configuration
        if len(h["frame"]):
            got.append(h)
    if not got:
        return None, NO_FOLDS
    per_fold = np.array([[np.sum(g["px2"] - g["px2_expected"]), np.sum(g["px2_held"]),
                          np.sum(g["px2_expected"]), fold_noise_variance(g)] for g in got])  # fmt: skip
    share = held_share(*per_fold.T)
    h = {k: np.concatenate([g[k] for g in got]) for k in got[0]}
    # one size m per tool-point coordinate, m / L per rotation coordinate (L the tool point's
    # distance to the board points in view: the rotation then moves the view about as much as
    # the translation), from the pixels' excess over what the rest explains: m^2 (u + w), its
    # effect in the frame itself and through the fold's estimate (misfit.py)
    m, reach, gram = 0.0, 0.0, None
    if counted_excess(got, share, variance) > 0:
        y = h["px2"] - h["px2_expected"] - share.point * h["px2_held"]
        m, reach, gram = grown_size(y, h["px2_var"], h["px2_unit"], h["px2_misfit"],
                                    h["distance"])  # fmt: skip
    r2, s2, n2 = ([x] for x in pose_error_terms(h, POSITION))
    r2r, s2r, n2r = ([x] for x in pose_error_terms(h, ORIENTATION))
    reached = float(np.max(h["distance"])) if span is not None else None  # None: not read
    me = model_error_of(r2, s2, n2, (r2r, s2r, n2r), folds=len(got),
                        failed=selection.folds_counting - len(got),
                        noise_what="the pixel and joint read-back noise",
                        given=(m, m / float(np.mean(h["lever"]))),
                        reach_distance=reach, growth=gram, measured_to=reached)  # fmt: skip
    if me is not None:  # the same rows' excess with each in its own metric (drift check)
        e, V, between = whitened_rows(got)
        me = with_whitened(me, e, V, POSITION, ORIENTATION, between)
    if me is None or variance is None:
        return me, share
    # the deviation's share the calibration counts (its covariance's), at the held-out rows
    held = share.used * np.trace(h["S_held"][:, :3, :3], axis1=1, axis2=2)
    held_rot = share.used * np.trace(h["S_held"][:, 3:, 3:], axis1=1, axis2=2)
    return dataclasses.replace(me, held_rms_m=float(np.sqrt(max(np.mean(held), 0.0))),
                               held_rms_rad=float(np.sqrt(max(np.mean(held_rot), 0.0)))), share  # fmt: skip


def _errors_px_mm(obs: BoardObservations, fit: Refinement,
                  frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Every camera's inlier rows of ``frames`` predicted by ``fit``: the 2-D error (k,) px and
    mm at the board (the detected pixel's ray met with the board plane at the predicted pose,
    against the predicted corner)."""
    px, mm = [], []
    for cam, _, Xc, uv, normal in predicted_points(obs, fit, frames):
        px.append(np.linalg.norm(cam.project(Xc) - uv, axis=1))
        d = cam.unproject(uv)  # the detected pixels' rays (camera frame)
        s = np.sum(normal * Xc, axis=1) / np.sum(normal * d, axis=1)
        mm.append(1e3 * np.linalg.norm(s[:, None] * d - Xc, axis=1))
    return (np.concatenate(px), np.concatenate(mm)) if px else (np.zeros(0), np.zeros(0))


def cross_validated_reprojection(obs: BoardObservations, selection: Selection) -> dict | None:
    """The cross-validated reprojection of the chosen candidate and of the fair nominal (module
    docstring): per model its 2-D RMS in px and mm at the board over every held-out row of the
    folds that count (:meth:`Selection.counts`; ``folds_counting`` says how many when not all
    do: an int, where the selection's block has ``folds_counted``, a flag per fold), None for
    a model a counted fold's fit failed for; None without folds."""
    if selection.fold_of is None:
        return None
    chosen = selection.candidates[selection.chosen]
    out: dict = {
        "what": "every fold's frames predicted from their joints alone by the model fitted "
        "without them (leave-one-configuration-out): 2-D RMS over the held-out corners in px and "
        "in mm at the board",
        "configurations": selection.configurations,
        "folds": selection.folds,
    }
    if selection.folds_counting < selection.folds:  # how many of the selection's `folds_counted`
        out["folds_counting"] = selection.folds_counting
        out["what"] += (": the folds that count, a fold leaving out more than half of the frames "
                        "not (its fit stands for a smaller experiment than the calibration)")  # fmt: skip
    for key, cand in (("calibrated", chosen), ("nominal", selection.candidates[0])):
        px, mm = [], []
        fitted = 0
        for f, (fit, _, _) in sorted(cand.fold_fits.items()):
            if not selection.counts(f):
                continue
            e_px, e_mm = _errors_px_mm(obs, fit, selection.fold_of == f)
            px.append(e_px)
            mm.append(e_mm)
            fitted += 1
        if not px or fitted < selection.folds_counting:
            out[key] = None
            continue
        p, m = np.concatenate(px), np.concatenate(mm)
        out[key] = {
            "label": cand.label,
            "corners": int(p.size),
            "reprojection_rms_px": float(np.sqrt(np.mean(p**2))),
            "at_board_rms_mm": float(np.sqrt(np.mean(m**2))),
        }
    return out


def board_accuracy(obs: BoardObservations, selection: Selection, cr: BoardCramerRao,
                   offsets: np.ndarray, T_tool_point: np.ndarray, limits: np.ndarray, *,
                   pixel_sigma_px: float, count: int = SAMPLE_COUNT,
                   deviation: Deviation | None = None, tool_point: str = "the flange",
                   ) -> Accuracy:  # fmt: skip
    """The predicted accuracy of a board calibration (module docstring): ``cr`` its bounds at
    the estimate (the stored model, :func:`selfcal.calibration.board.bounds.board_bounds`),
    ``selection`` its parameter selection (the fold fits), ``offsets`` (n,) rad the joint
    offsets of the stored model's gauge, ``T_tool_point`` the flange in the chain's tool frame,
    ``limits`` (n, 2) rad / m the joint limits, ``pixel_sigma_px`` the corner noise the bounds
    used; ``count`` joint vectors per region; ``deviation``: how far the held parameters may
    lie from the drawing (default :class:`Deviation`'s; :mod:`selfcal.calibration.board.held`);
    ``tool_point``: what ``T_tool_point`` is, in words (the camera where the file has no mount)."""
    deviation = Deviation() if deviation is None else deviation
    variance = deviation.variance(cr.model.joint_types)
    span = joint_spans(limits, revolute_joints(cr.model.joint_types))
    me, share = model_error(obs, selection, offsets, T_tool_point, pixel_sigma_px, variance, span)
    noisy = cr  # the estimate's error from the pixels' and joints' noise alone (drift check)
    cr = with_deviation(cr, share.used * variance)
    pos = 0.0 if me is None else me.position_m
    rot = 0.0 if me is None or me.rotation_rad is None else me.rotation_rad
    q_cal = np.asarray(obs.q[obs.used], dtype=float)
    reach = None  # where it grows from and how far the folds tested the model (found or not)
    if me is not None and span is not None and (me.reach_distance > 0 or np.isfinite(me.limit)):
        reach = Reach(q_cal, span, me.reach_distance, me.reach_floor, unmeasured_beyond(me))
    em, names = board_error_model(cr, T_tool_point, pos, rot, reach)
    sample = workspace_sample(q_cal, limits, count=count)
    note = ("no cross-validation (the frames show one arm configuration): the covariance alone, "
            "which is optimistic when the model misfits")  # fmt: skip
    cols, C, n0 = bounds_covariance(cr)
    C = C + pos**2 * bounds_covariance(cr, misfit=True)[1]  # as `covariance_si` (the misfit's)
    p = len(C) - n0
    extra = {
        # the first camera's free parameters (its order) with their correlation to `estimated`:
        # the drift check's prediction of new pixels (selfcal/calibration/drift/images.py)
        "camera_covariance_si": C[p:, p:].tolist(),
        "camera_cross_si": C[:p, p:].tolist(),
        "noise_covariance_si": bounds_noise_covariance(noisy, cols).tolist(),
        "tool_point": tool_point,
        "T_tool_point_si": np.asarray(T_tool_point, float).tolist(),
        "joint_limits_si": np.asarray(limits, float).tolist(),
        **spans_json(span),
        "cross_validation": cross_validated_reprojection(obs, selection),
        "held_deviation": held_block(deviation, share),
    }
    return Accuracy(em, names, me, workspace_summary(em, sample, q_cal), sample, q_cal,
                    _what(obs.eye_to_hand, tool_point), note, extra)  # fmt: skip


def predicted_reprojection(cr: BoardCramerRao, camera: CameraModel, q: np.ndarray,
                           points: list[np.ndarray], T_tool_point: np.ndarray, *,
                           eye_to_hand: bool, joint_sigma: np.ndarray | float | None,
                           model_error_m: float, model_error_rad: float,
                           reach: Reach | None = None,
                           ) -> float:  # fmt: skip
    """The predicted 2-D RMS (px) of the reprojection errors of new frames of the first camera
    ``camera`` at the joints ``q`` (m, n) rad, ``points[i]`` (k_i, 3) the board points it sees in
    frame ``i`` (board frame, m): what the calibration's errors (kinematics and camera, ``cr``
    its bounds at the estimate, with what the model error in its frames gave the estimate:
    :attr:`BoardCramerRao.misfit`), the model error per tool-point coordinate (``model_error_m``,
    ``model_error_rad``), the joint read-back noise ``joint_sigma`` and the pixel noise
    (``cr.pixel_sigma_px``) give them, to first order -- to compare with ``selfcal evaluate``'s
    measured held-out RMS. ``reach``: where the model error grows from (the calibration
    postures, the joints' spans and the reference distance, :class:`Reach`; the joints it wraps:
    ``cr.model``'s revolute ones), or None."""
    cols, C, n0 = bounds_covariance(cr)
    C = C + model_error_m**2 * bounds_covariance(cr, misfit=True)[1]
    t = np.asarray(T_tool_point, float)[:3, 3]
    M = np.diag([model_error_m**2] * 3 + [model_error_rad**2] * 3)
    q = np.atleast_2d(q)
    grow = reach.factor(q, cr.model.joint_types) if reach is not None else np.ones(len(q))
    total, count = 0.0, 0
    for qi, X, g in zip(q, points, grow, strict=True):
        T = fk_tool(cr.model, qi[None])[0]
        x, _, A, Jc = board_view(camera, T, X, eye_to_hand)
        H = np.concatenate([A @ identification_jacobian(cr.model, qi[None])[0][:, cols],
                            Jc.reshape(-1, n0)], axis=1)  # fmt: skip
        Binv = np.linalg.inv(tip_map(T, t))
        cov = H @ C @ H.T + g * (A @ Binv @ M @ Binv.T @ A.T)
        if joint_sigma is not None:
            tw = A @ joint_twists(cr.model, qi[None])[0]
            cov = cov + tw @ np.diag(np.broadcast_to(np.asarray(joint_sigma, float) ** 2,
                                                     (tw.shape[1],))) @ tw.T  # fmt: skip
        total += float(np.trace(cov)) + 2 * len(x) * cr.pixel_sigma_px**2
        count += len(x)
    return float(np.sqrt(total / max(count, 1)))


def board_error_model_from_json(block: dict, model: MCPCModel, where: str) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of a board ``calibration.json``'s ``accuracy`` block.

    Raises:
        InputError: the block is malformed (named).
    """
    names = tuple(param_names(minimal_indices(model.joint_types)))
    tip = np.asarray(block.get("T_tool_point_si", np.eye(4)), dtype=float)
    return error_model_from_json(block, model, np.eye(4), names, True, where, fix=_FIX,
                                 T_tool_point=tip)  # fmt: skip


def board_postures_from_json(block: dict, n: int, where: str) -> np.ndarray:
    """The calibration postures (m, n) rad / m of a board ``accuracy`` block."""
    return postures_from_json(block, n, where, fix=_FIX)
