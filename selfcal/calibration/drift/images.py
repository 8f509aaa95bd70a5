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
whole check from the files (``selfcal check`` and the public API). Nothing here reads truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.linalg import solve_triangular

from selfcal.calibration.board.accuracy import board_error_model_from_json, board_postures_from_json
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.folds import unseen
from selfcal.calibration.drift.attribution import Attribution, attribute, candidate_fits
from selfcal.calibration.drift.covariance import estimate_covariance, view_covariance
from selfcal.calibration.drift.fold_error import fold_error_model
from selfcal.calibration.drift.gross import gross_miss
from selfcal.calibration.drift.noisy import (
    Noisy,
    noisy_frame_line,
    noisy_frames,
    noisy_line,
    noisy_views,
)
from selfcal.calibration.drift.outliers import Outlier, drop_outliers, outlier_line
from selfcal.calibration.drift.own import JOINT_TOL, calibration_frames, own_views
from selfcal.calibration.drift.p_value import combined_p, min_p, p_text, smallest_p
from selfcal.calibration.drift.paired import noise_covariance, paired_views, posture_tol
from selfcal.calibration.drift.power import ShiftPower, shift_power
from selfcal.calibration.drift.tool_moves import BOUND_LEVEL, kinematic_bound_mm, tool_point_moves
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
    "ImageDriftCheck",
    "UNSEEN_NOTE",
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
UNSEEN_NOTE = (
    "the check's false-alarm rate at configurations a calibration did not see is measured in "
    "simulation only; on real arms it has said changed for unchanged ones (the real sets' "
    "folds, docs/real-data.md): check again at the calibration's own postures before acting"
)
"""What a "changed" verdict adds when views are at arm configurations the calibration did not
see (issue #29: each real Nachi set's held-out configurations, docs/real-data.md)."""
OWN_NOTE = (
    "a change the calibration absorbed cannot show in them: check with images recorded since "
    "the calibration"
)
"""What a verdict says of new images that are the calibration's own frames (their joint
readings and board detections, :mod:`selfcal.calibration.drift.own`): left out of the test."""
CANNOT_TELL_NOTE = (
    "a change this small cannot be told from how the calibration predicts configurations it did "
    "not see; check with images at the calibration's own postures (paired with its frames "
    "there) or calibrate with these configurations"
)
"""What a "cannot tell" verdict adds (:func:`fold_recheck`)."""


@dataclass(frozen=True)
class ImageDriftCheck:
    """Outcome of :func:`image_drift_check`.

    Attributes:
        views, corners: what was compared; statistic, dof, p_value: the chi-square test;
        changed: ``p_value < alpha``; rms_px: the residuals' 2-D RMS; expected_rms_px: what
        ``Sigma`` predicts for it; best: the candidate change that fits best
        (:meth:`selfcal.calibration.drift.attribution.Fits.best`); change_mm: the RMS over the views of the tool point's move by it (0 for
        the camera); mean_tip_mm: (3,) its mean (world frame); attribution: what changed, or
        None when unchanged; unseen: how many views are at an arm configuration none of the
        calibration's postures has (:func:`selfcal.calibration.board.folds.unseen`; 0 where
        not known): the check's false-alarm rate there is measured in simulation only
        (:data:`UNSEEN_NOTE`); own: how many new images are the calibration's own frames
        (:mod:`selfcal.calibration.drift.own`), left out of the test (``views`` counts the
        others; none left: nothing tested, ``p_value`` 1, ``expected_rms_px`` NaN and
        ``rms_px`` their fit's RMS); tool_bound_mm: when the best change is the camera's (it
        moves no tool point), the largest RMS tool-point move a kinematic change fitted beside
        it reaches at :data:`BOUND_LEVEL` confidence (:func:`~selfcal.calibration.drift.tool_moves.kinematic_bound_mm`; 0 otherwise);
        turn_deg: the RMS over the views of the tool's rotation by the best change (deg; the
        verdict gives it where the tool point moves less than 0.001 mm, as a wrist joint's
        offset turns the tool about the flange); paired: how many of the ``views`` were
        tested against the calibration's frame at the same posture, repeated: how many more
        there were tested as new (:mod:`selfcal.calibration.drift.paired`). undecided: "cannot
        tell": failed, but not with the folds' error fold_error_mm / _deg per coordinate
        (:func:`fold_recheck`; 0 when not applied) as the views' model error (p fold_p_value),
        or not failed but with views noisier than the calibration's frames (``noisy``, each
        tested with its own noise: :mod:`selfcal.calibration.drift.noisy`; fold_p_value NaN).
        noisy_frames: paired views whose frame, the calibration's own image at that posture,
        is the noisy one (each the new image's name, the frame's noise and the calibration's,
        px; named in the line, the verdict unchanged by them).
        outliers: the corners left out by the calibration's outlier rule
        (:mod:`selfcal.calibration.drift.outliers`). power: what the check of these views
        finds of a 0.2 mm move of the mount (:mod:`selfcal.calibration.drift.power`; None
        where not computed: :func:`image_drift_check` alone). gross: the words naming a miss
        beyond half the image's width as a likely input error, "" otherwise
        (:mod:`selfcal.calibration.drift.gross`; in the line of a change).
    """

    views: int
    corners: int
    statistic: float
    dof: int
    p_value: float
    changed: bool
    rms_px: float
    expected_rms_px: float
    change_mm: float
    mean_tip_mm: np.ndarray
    alpha: float
    best: str = ""
    attribution: Attribution | None = None
    unseen: int = 0
    own: int = 0
    tool_bound_mm: float = 0.0
    turn_deg: float = 0.0
    paired: int = 0
    repeated: int = 0
    undecided: bool = False
    fold_error_mm: float = 0.0
    fold_error_deg: float = 0.0
    fold_p_value: float = float("nan")
    outliers: tuple[Outlier, ...] = ()
    noisy: tuple[Noisy, ...] = ()
    noisy_frames: tuple[Noisy, ...] = ()
    power: ShiftPower | None = None
    gross: str = ""
    p_parts: tuple[float, int] | None = None
    fold_p_parts: tuple[float, int] | None = None

    def _p(self, fold: bool = False) -> str:
        """``p_value`` (``fold``: ``fold_p_value``) as the line prints it; Bonferroni's bound
        clipped at 1 says so with the smallest of its tests' p-values (``p_parts``: that and
        their count, None where not Bonferroni's)."""
        p, parts = (self.fold_p_value, self.fold_p_parts) if fold else (self.p_value, self.p_parts)
        return p_text(p) if parts is None else p_text(p, *parts)

    def _own_line(self) -> str:
        out = outlier_line(self.outliers)
        if self.noisy_frames:
            out += f"; {noisy_frame_line(self.noisy_frames)}"
        if not self.own:
            return out
        return out + (f"; {self.own} more image(s) are the calibration's own (its frames' joint "
                f"readings and board detections), left out of the test: {OWN_NOTE}")  # fmt: skip

    def line(self) -> str:
        """The verdict in one line."""
        what = f"{self.views} new image(s), {self.corners} corners"
        if self.paired:
            again = f", {self.repeated} more there tested as new" if self.repeated else ""
            what += (f" ({self.paired} at the calibration's postures, each against its frame "
                     f"there{again})")  # fmt: skip
        fit = (f"{what}: {self.rms_px:.3f} px RMS against the predicted "
               f"{self.expected_rms_px:.3f} px; {self._p()} < {self.alpha:g}")  # fmt: skip
        if self.changed and self.best == "camera":
            out = (f"changed (the best single change, the camera's intrinsics, moves no tool "
                   f"point; a change of a mount or of one joint's offset fitted beside it "
                   f"moves the tool point, the flange, by at most {self.tool_bound_mm:.3f} mm "
                   f"RMS at {BOUND_LEVEL:.0%} confidence; {fit})")  # fmt: skip
        elif self.changed and self.change_mm < 5e-4:  # it turns the tool about its point
            out = (f"changed (the best single change, {self.best}, moves the tool point, the "
                   f"flange, by less than 0.001 mm and turns the tool by {self.turn_deg:.4f} "
                   f"deg RMS; {fit})")  # fmt: skip
        elif self.changed:
            out = (f"changed by {self.change_mm:.3f} mm at the tool point (the flange, as the "
                   f"best single change, {self.best}, fits it; {fit})")  # fmt: skip
        if self.undecided and not np.isfinite(self.fold_p_value):  # noisy views, not failed
            return (f"cannot tell: {what} within the calibration's prediction with their own "
                    f"noise ({self.rms_px:.3f} px RMS, predicted {self.expected_rms_px:.3f} px; "
                    f"{self._p()}), but {noisy_line(self.noisy)}" + self._own_line())  # fmt: skip
        if self.undecided:
            noisy = f"; {noisy_line(self.noisy)}" if self.noisy else ""
            return (f"cannot tell: {fit}, but this calibration's own folds missed the arm "
                    f"configurations they left out by {self.fold_error_mm:.3f} mm and "
                    f"{self.fold_error_deg:.3f} deg of tool pose per coordinate beyond their "
                    f"estimate and noise, and with that error the new images fit "
                    f"({self._p(fold=True)}): {CANNOT_TELL_NOTE}{noisy}" + self._own_line())  # fmt: skip
        if self.changed:
            out = out if self.attribution is None else f"{out}; {self.attribution.line()}"
            out += f"; {self.gross}" if self.gross else ""
            if np.isfinite(self.fold_p_value):
                out += (f"; changed also with the calibration's own folds' error at "
                        f"configurations they left out ({self.fold_error_mm:.3f} mm, "
                        f"{self.fold_error_deg:.3f} deg per coordinate; "
                        f"{self._p(fold=True)})")  # fmt: skip
            elif self.unseen:
                out += (f"; {self.unseen} of {self.views} image(s) at arm configurations the "
                        f"calibration did not see: {UNSEEN_NOTE}")  # fmt: skip
            return out + self._own_line()
        return (f"unchanged: {what} within the calibration's prediction ({self.rms_px:.3f} px "
                f"RMS, predicted {self.expected_rms_px:.3f} px; {self._p()})"
                + self._own_line())  # fmt: skip

    def to_json(self) -> dict:
        """The result as JSON (px, mm)."""
        return {
            "verdict": "changed"
            if self.changed
            else "cannot tell"
            if self.undecided
            else "unchanged",
            "line": self.line(),
            "images": self.views,
            "own_images": self.own,
            "paired_images": self.paired,
            "repeated_posture_images": self.repeated,
            "corners": self.corners,
            "statistic": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "p_value_tests": None
            if self.p_parts is None
            else {
                "count": self.p_parts[1],
                "smallest_p_value": self.p_parts[0],
                "note": "p_value is Bonferroni's bound: count times the smallest, at most 1",
            },
            "alpha": self.alpha,
            "rms_px": self.rms_px,
            "expected_rms_px": (
                self.expected_rms_px if np.isfinite(self.expected_rms_px) else None
            ),  # fmt: skip
            "change_mm": self.change_mm,
            "tool_bound_mm": self.tool_bound_mm,
            "turn_deg": self.turn_deg,
            "best_single_change": self.best,
            "mean_tool_point_mm": self.mean_tip_mm.tolist(),
            "cause": None if self.attribution is None else self.attribution.to_json(),
            "unseen_configuration_images": self.unseen,
            "noisy_images": [
                {"image": n, "white_px": w, "calibration_white_px": c} for n, w, c in self.noisy
            ],
            "noisy_calibration_images": [
                {"at_image": n, "white_px": w, "calibration_white_px": c}
                for n, w, c in self.noisy_frames
            ],
            "outlier_corners": [
                {"image": n, "u_px": u, "v_px": v, "error_px": e} for n, u, v, e in self.outliers
            ],
            "fold_model_error_mm": self.fold_error_mm,
            "fold_model_error_deg": self.fold_error_deg,
            "p_value_with_fold_error": (
                self.fold_p_value if np.isfinite(self.fold_p_value) else None
            ),  # fmt: skip
            "mount_shift_power": None if self.power is None else self.power.to_json(),
        }


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
