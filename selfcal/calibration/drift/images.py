"""Drift check: do new images still fit a board calibration? (issue #29)

New views of the calibration's board (the first camera's images, joint readings at any
postures) are compared with what the calibration predicts from the joints alone: the board
points ``X`` (board frame) seen from the calibrated chain, ``uv = camera(T_cam_board(q) X)``
(eye-in-hand ``T_cam_board = inv(fk(q))``, the board pose part of the chain; eye-to-hand
``fk(q)``, the camera's pose part of it). Under "unchanged" the stacked residuals ``r = detected -
predicted`` (2k px over every corner of every view) are Gaussian to first order with covariance

    Sigma = H C H^T + blockdiag_i(A_i B_i^-1 M B_i^-T A_i^T + A_i J A_i^T + Q_i S_j Q_i^T)
            + s^2 I

- ``H C H^T``: the calibration's estimation error, correlated between the views through the
  shared parameters: ``H = [A J_id, J_cam]`` the pixels' derivative by the estimated kinematic
  parameters and the first camera's free parameters, ``C`` their joint covariance (the
  ``accuracy`` block's, :func:`estimate_covariance`; a board calibration's covers the
  parameters it held at the drawing too, with the share of their deviation its folds showed:
  :mod:`selfcal.calibration.board.held_prior`);
- the model error ``M`` per view (the ``accuracy`` block's ``m`` per tool-point coordinate and
  per rotation coordinate, :mod:`selfcal.calibration.board.accuracy`), ``A`` the pixels'
  derivative by a body twist of the chain's tool, ``B`` its map to the tool point (the flange);
- the joint read-back noise ``S_j`` (``bounds.joint_sigma_deg``) through the joints' twists
  ``Q = A tw``; the corner noise ``s`` (``bounds.pixel_sigma_px``);
- when the calibration's own frames showed a per-view misfit (the ``accuracy`` block's
  ``view_jitter``, :mod:`selfcal.calibration.board.view_jitter`): ``A_i J A_i^T + c^2 U_i U_i^T``
  per view, ``J`` (6, 6) the jitter of the chain's tool pose (or ``g^2 P_i``, a misfit ``g``
  per direction of the view's pose span, ``P_i`` the projection on it, where the block gives
  ``pose_misfit_px``), ``c`` the misfit per camera direction ``U_i`` (orthonormal, outside the
  pose span), and ``s`` is then the block's white noise outside both (the bounds' from the
  fit's RMS holds the misfit's energy: it counted it twice);
- each new view's own white corner noise in place of ``s`` where its pixels outside its pose
  span and the camera's directions (which no change considered and no estimation error reach)
  show more at :data:`selfcal.calibration.drift.views.WHITE_LEVEL`
  (:func:`selfcal.calibration.drift.views.view_white_px`): real images differ in their noise,
  and one noisier than the calibration's frames read as a change (two of the real Nachi sets'
  left-out configurations, docs/real-data.md); those pixels are also where a change the check
  does not model shows (a held lens term, the focus, the board), which that noise hides, so a
  check of such views that does not fail says "cannot tell", not "unchanged"
  (:mod:`selfcal.calibration.drift.noisy`).

``T = r^T Sigma^-1 r`` is then chi-square with ``2k`` degrees of freedom. That omnibus test
has little power against a change that moves the pixels along a few directions (a joint's
offset, a mount) among ``2k`` (hundreds), so each candidate change of
:mod:`selfcal.calibration.drift.attribution` (the camera, the chain's tool mount's translation
and its rotation, its world's translation and rotation, one joint's offset) is also tested: how
much its fit lowers ``T`` is chi-square with its parameter count. The robot has changed when
the smallest of these ``1 + 5 + n`` p-values, times their count (Bonferroni,
:func:`selfcal.calibration.drift.p_value.combined_p`), is below ``alpha`` (0.01): when
``Sigma`` is right, at most ``alpha`` of the checks of an unchanged robot say "changed". Where
the calibration's frames showed a per-view misfit, a failed test is run again with its own
folds' error at the configurations they left out as each view's model error
(:mod:`selfcal.calibration.drift.fold_error`, :func:`fold_recheck`): "changed" only if it fails
that too, else "cannot tell" (on real arms ``Sigma`` is wrong at a new configuration).

Corners the calibration's outlier rule would drop are left out and named
(:mod:`selfcal.calibration.drift.outliers`). New images that are the calibration's own frames (the same joint readings and detections) are
left out of the test and counted (:mod:`selfcal.calibration.drift.own`: their residuals are the
fit's, not independent of its estimate; the test read them as a camera change on a real set).
New images at a calibration frame's posture, when its frames showed a per-view misfit, are tested
by their residuals' difference from that frame's (:mod:`selfcal.calibration.drift.paired`: the
misfit of that posture and the estimate's error cancel; ``Sigma``'s blocks of them are both
views' noise, with no ``H C H^T``, and their blocks with an unpaired view ``H_b C_e H_u^T``, the
frame's noise in the estimate); without a misfit the new view alone is the stronger test (its
noise once, not twice).

The change at the tool: the RMS over the new postures of the tool point's (the flange's) move
by the best-fitting candidate change; the camera (no tool point move) gives the bound of a
kinematic change fitted beside it
(:func:`selfcal.calibration.drift.tool_moves.kinematic_bound_mm`).

What changed (:mod:`selfcal.calibration.drift.attribution`) is named only when one kind of
small change alone explains the residuals. Only the first camera is checked (a rig's other
cameras' extrinsics have no covariance in ``calibration.json``). :func:`check_images` is the
whole check from the files (``selfcal check`` and the public API); its outcome, the verdict's
line and JSON: :class:`selfcal.calibration.drift.verdict.ImageDriftCheck`. Nothing here reads
truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.linalg import solve_triangular

from selfcal.calibration.board.accuracy import board_error_model_from_json, board_postures_from_json
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.folds import unseen
from selfcal.calibration.drift.attribution import attribute, candidate_fits
from selfcal.calibration.drift.covariance import estimate_covariance, view_covariance
from selfcal.calibration.drift.fold_error import fold_error_model
from selfcal.calibration.drift.gross import gross_miss
from selfcal.calibration.drift.noisy import (
    noisy_frames,
    noisy_views,
)
from selfcal.calibration.drift.outliers import drop_outliers
from selfcal.calibration.drift.own import JOINT_TOL, calibration_frames, own_views
from selfcal.calibration.drift.p_value import combined_p, min_p, smallest_p
from selfcal.calibration.drift.paired import noise_covariance, paired_views, posture_tol
from selfcal.calibration.drift.power import shift_power
from selfcal.calibration.drift.tool_moves import kinematic_bound_mm, tool_point_moves
from selfcal.calibration.drift.verdict import ImageDriftCheck
from selfcal.calibration.drift.views import (
    ViewJacobians,
    ViewNoise,
    calibration_views,
    view_noise,
)
from selfcal.errors import InputError
from selfcal.io.board_calibration import (
    BoardCalibrationResult,
    calibration_kind,
    read_board_calibration,
)
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.threads import limited

__all__ = [
    "ALPHA",
    "ViewNoise",
    "calibration_error_model",
    "check_images",
    "estimate_covariance",
    "fold_recheck",
    "image_drift_check",
    "view_noise",
]

ALPHA = 0.01
"""The false-alarm probability the check allows on an unchanged robot."""


def image_drift_check(C: np.ndarray, views: list[ViewJacobians], *,
                      eye_to_hand: bool, camera_names: tuple[str, ...] = (),
                      alpha: float = ALPHA, exact: bool = False,
                      C_noise: np.ndarray | None = None,
                      names: tuple[str, ...] = ()) -> ImageDriftCheck:  # fmt: skip
    """Test the linearised ``views`` (:func:`view_jacobians`) against the calibration's
    estimate covariance ``C`` (p + c, p + c) of its estimated kinematic parameters and the
    camera's free parameters (:func:`estimate_covariance`; module docstring; ``camera_names``
    the camera's free parameters' names for the attribution). ``exact``: the tests combined by
    their smallest p-value's distribution under "unchanged"
    (:func:`selfcal.calibration.drift.p_value.min_p`, Monte Carlo) rather than Bonferroni's
    bound, which the tests' correlation makes conservative; the default stays Bonferroni
    (``python -m selfcal.benchmarks.drift.images --min-p`` measures the difference).
    ``C_noise``: the part of ``C`` from the calibration frames' noise
    (:func:`noise_covariance`), for a paired view's correlation with the others (None: left
    out). Not failed, with a view tested with its own noise (noisier than the calibration's
    frames): "cannot tell" (:mod:`selfcal.calibration.drift.noisy`; ``names`` the views' images
    for the verdict, default "view 1", "view 2" ...).

    Raises:
        InputError: no view.
    """
    if not views:
        raise InputError("drift check: no view of the board to compare",
                         fix="give images that show the board")  # fmt: skip
    r = np.concatenate([v.r for v in views])
    sigma = view_covariance(C, views, C_noise)
    L = np.linalg.cholesky(sigma)

    def white(M: np.ndarray) -> np.ndarray:
        return solve_triangular(L, M, lower=True)

    rw = white(r)
    T = float(rw @ rw)
    dof = len(r)
    # the omnibus test and each candidate change's directed one (how much its fit lowers T,
    # chi-square with its rank), Bonferroni-combined
    fits = candidate_fits(white, rw, views, eye_to_hand=eye_to_hand)
    p = (min_p(T, dof, fits.directed, fits.directed_columns) if exact
         else combined_p(T, dof, fits.directed))  # fmt: skip
    parts = None if exact else smallest_p(T, dof, fits.directed)
    best = fits.best(T)
    twists = tool_point_moves(best, fits.x[best], views)
    moves = twists[:, :3]
    changed = p < alpha
    noisy = noisy_views(views, names)
    bound = kinematic_bound_mm(fits, rw, views) if changed and best == "camera" else 0.0
    return ImageDriftCheck(
        views=len(views),
        corners=dof // 2,
        statistic=T,
        dof=dof,
        p_value=p,
        changed=changed,
        rms_px=float(np.sqrt(np.sum(r**2) / (dof // 2))),
        expected_rms_px=float(np.sqrt(np.trace(sigma) / (dof // 2))),
        change_mm=float(np.sqrt(np.mean(np.sum(moves**2, axis=1)))) * 1e3,
        turn_deg=float(np.degrees(np.sqrt(np.mean(np.sum(twists[:, 3:] ** 2, axis=1))))),
        mean_tip_mm=moves.mean(axis=0) * 1e3,
        best=best,
        alpha=alpha,
        attribution=attribute(fits, T, dof, views, camera_names=camera_names, alpha=alpha)
        if changed else None,
        tool_bound_mm=bound,
        undecided=not changed and bool(noisy),
        noisy=noisy,
        noisy_frames=noisy_frames(views, names),
        p_parts=parts,
    )  # fmt: skip


def fold_recheck(res: ImageDriftCheck, wide: ToolErrorModel | None,
                 views_of: Callable[[ToolErrorModel], list[ViewJacobians]], C: np.ndarray, *,
                 eye_to_hand: bool, alpha: float = ALPHA,
                 C_noise: np.ndarray | None = None) -> ImageDriftCheck:  # fmt: skip
    """The verdict ``res`` of the views ``views_of(em)``, when it says changed, tested again at
    ``wide`` (:func:`selfcal.calibration.drift.fold_error.fold_error_model`, the calibration's
    folds' error at configurations they left out as the model error; None: ``res`` stands):
    changed when they fail that too, else "cannot tell" (``undecided``); ``C``, ``C_noise`` as
    before."""
    if not res.changed or wide is None:
        return res
    again = image_drift_check(C, views_of(wide), eye_to_hand=eye_to_hand, alpha=alpha,
                              C_noise=C_noise)  # fmt: skip
    res = replace(res, fold_error_mm=wide.model_error_m * 1e3, fold_p_value=again.p_value,
                  fold_p_parts=again.p_parts,
                  fold_error_deg=float(np.degrees(wide.model_error_rad or 0.0)))  # fmt: skip
    if again.changed:
        return res
    return replace(res, changed=False, undecided=True, attribution=None, tool_bound_mm=0.0)


def calibration_error_model(cal: BoardCalibrationResult, where: str) -> ToolErrorModel:
    """The calibration's :class:`ToolErrorModel` (its ``accuracy`` block).

    Raises:
        InputError: no accuracy or bounds block (named, with the fix).
    """
    if cal.accuracy is None or cal.bounds is None:
        raise InputError(
            f"{where} has no accuracy or bounds block (written before them, or the bounds "
            "failed: see its bounds_error)",
            fix="re-run `selfcal calibrate` on the calibration's dataset",
        )
    return board_error_model_from_json(cal.accuracy, cal.model, where)


@limited
def check_images(calibration: str | Path, new_data: str | Path, *,
                 alpha: float = ALPHA) -> ImageDriftCheck:  # fmt: skip
    """Check the first camera's images of the dataset ``new_data`` (the format ``selfcal
    calibrate`` reads: a few images of the calibration's board with joint readings, any
    postures) against the board calibration ``calibration`` (the folder of ``selfcal
    calibrate`` or its ``calibration.json``) with its ``accuracy`` and ``bounds`` blocks
    (module docstring). New images that are the calibration's own frames (their joint readings
    and detections, :mod:`selfcal.calibration.drift.own`) are left out of the test and counted.
    The result states the check's power for the views tested (``power``,
    :mod:`selfcal.calibration.drift.power`).

    Raises:
        InputError: the calibration is missing, not a board calibration or has no accuracy
            block; ``alpha`` is not a probability; the dataset is not of the calibration's
            robot, board, camera or setup, or no image shows the board (named); every new
            image is one of the calibration's own frames (nothing to test).
    """
    src = Path(calibration)
    path = src / "calibration.json" if src.is_dir() else src
    if not path.is_file():
        raise InputError(f"{path} not found", fix="give the DIR `selfcal calibrate` wrote")
    if calibration_kind(path) != "board":
        raise InputError(f"{path} is not a board calibration", fix="give the calibration of "
                         "`selfcal calibrate` on images of a board")  # fmt: skip
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha {alpha} is not a probability", fix="e.g. alpha 0.01")
    cal = read_board_calibration(path)
    em = calibration_error_model(cal, str(path))
    held = held_out_views(cal, new_data, cameras=(cal.camera_names[0],), cal_file=path)
    noise = view_noise(cal, str(path))
    tol = posture_tol(noise.joint_sigma_rad, cal.model.n) if noise.misfit_counted else JOINT_TOL
    mine = calibration_frames(cal, path, held, cal.camera_names[0], tol)
    own = own_views(cal, path, held, mine)
    new = [(f, X, uv) for (_, f, _, _, X, uv), o in zip(held.views, own, strict=True) if not o]
    names = tuple(v[0] for v, o in zip(held.views, own, strict=True) if not o)
    new, outliers = drop_outliers(em, cal.cameras[0], held.q, new, list(names),
                                  eye_to_hand=cal.eye_to_hand)  # fmt: skip
    if not new:  # every image is the calibration's own: nothing the test may use
        raise InputError(
            f"{new_data}: all {len(held.views)} image(s) are the calibration's own frames (their "
            f"joint readings and board detections, as in {path.parent}): a check of them cannot "
            "find a change, since the calibration fitted them",
            fix="give images recorded after the calibration at a few postures (`selfcal import "
            "... --out NEW` of them with their joint readings; `selfcal acquire` in simulation), "
            "not the calibration's dataset",
        )
    q_cal = board_postures_from_json(cal.accuracy or {}, cal.model.n, str(path))

    def views_of(m: ToolErrorModel) -> list[ViewJacobians]:
        views = calibration_views(cal, m, held.q, new, where=str(path))
        return paired_views(cal, path, held, mine, new, views, em=m, noise=noise)[0]

    views = calibration_views(cal, em, held.q, new, where=str(path))
    tested, repeated = paired_views(cal, path, held, mine, new, views, em=em, noise=noise)
    C, C_noise = estimate_covariance(cal, em), noise_covariance(cal, em)
    res = image_drift_check(C, tested, eye_to_hand=cal.eye_to_hand,
                            camera_names=cal.cameras[0].free, alpha=alpha, C_noise=C_noise,
                            names=names)  # fmt: skip
    wide = fold_error_model(em, cal.accuracy, noise.misfit_counted)
    res = fold_recheck(res, wide, views_of, C, eye_to_hand=cal.eye_to_hand, alpha=alpha,
                       C_noise=C_noise)  # fmt: skip
    power = shift_power(C, tested, eye_to_hand=cal.eye_to_hand, alpha=alpha, C_noise=C_noise,
                        upper=wide is not None)  # fmt: skip
    far = unseen(held.q[[f for f, _, _ in new]], q_cal, cal.model.joint_types)
    return replace(res, unseen=int(np.count_nonzero(far)), own=int(np.count_nonzero(own)),
                   paired=sum(v.paired for v in tested), repeated=repeated,
                   outliers=outliers, power=power,
                   gross=gross_miss(res.rms_px, cal.cameras[0].width,
                                    Path(held.root) / "joints.csv"))  # fmt: skip
