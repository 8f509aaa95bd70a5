"""The image drift check's outcome (:class:`ImageDriftCheck`): its verdict in one line and as
JSON, with what each kind of verdict adds (:data:`UNSEEN_NOTE`, :data:`OWN_NOTE`,
:data:`CANNOT_TELL_NOTE`). The test that reaches it:
:func:`selfcal.calibration.drift.images.image_drift_check` (its module docstring gives the
covariance and the tests); from the files: :func:`selfcal.calibration.drift.images.check_images`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.drift.attribution import Attribution
from selfcal.calibration.drift.noisy import Noisy, noisy_frame_line, noisy_line
from selfcal.calibration.drift.outliers import Outlier, outlier_line
from selfcal.calibration.drift.p_value import p_text
from selfcal.calibration.drift.power import ShiftPower
from selfcal.calibration.drift.tool_moves import BOUND_LEVEL

__all__ = ["CANNOT_TELL_NOTE", "ImageDriftCheck", "OWN_NOTE", "UNSEEN_NOTE"]

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
"""What a "cannot tell" verdict adds (:func:`selfcal.calibration.drift.images.fold_recheck`)."""


@dataclass(frozen=True)
class ImageDriftCheck:
    """Outcome of :func:`selfcal.calibration.drift.images.image_drift_check`.

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
        (:func:`~selfcal.calibration.drift.images.fold_recheck`; 0 when not applied) as the views' model error (p fold_p_value),
        or not failed but with views noisier than the calibration's frames (``noisy``, each
        tested with its own noise: :mod:`selfcal.calibration.drift.noisy`; fold_p_value NaN).
        noisy_frames: paired views whose frame, the calibration's own image at that posture,
        is the noisy one (each the new image's name, the frame's noise and the calibration's,
        px; named in the line, the verdict unchanged by them).
        outliers: the corners left out by the calibration's outlier rule
        (:mod:`selfcal.calibration.drift.outliers`). power: what the check of these views
        finds of a 0.2 mm move of the mount (:mod:`selfcal.calibration.drift.power`; None
        where not computed: :func:`~selfcal.calibration.drift.images.image_drift_check` alone). gross: the words naming a miss
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
