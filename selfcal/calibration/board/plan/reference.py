"""What a plan's calibration has to beat: the tool-point error without calibrating the
kinematics, predicted for the same postures (``selfcal plan``, issue #30; the developers'
guide's fair reference).

Two figures, both of the quantity the plan predicts (the flange centre, a point fixed to what
rides on the flange, over the workspace after the best rigid alignment):

- the fair nominal: the chain held at its drawing, its placement (eye-in-hand the board pose
  ``V_0`` and the hand-eye ``V_n``; eye-to-hand base -> camera and flange -> board) and the
  camera's free parameters fitted to the pixels, as the calibration's own fair nominal is
  (:mod:`selfcal.calibration.board.nominal_fit`): the prediction of
  :func:`selfcal.calibration.board.plan.predict.predicted_with_held` with the placement's
  directions alone, i.e. the held parameters' deviation less what the fitted placement absorbs,
  plus the placement's and the camera's noise. The fit matches the camera's poses, not the
  flange: the hand-eye that takes up the chain's deviation where the camera sees the board
  carries it to the flange, so this is often the worse of the two;
- the chain as drawn, nothing fitted (the controller's own kinematics and the mount as drawn):
  the deviation itself at the tool point, ``sqrt(trace(G S))`` with ``G`` the aligned tool
  weight and ``S`` the deviation's covariance of every minimal parameter
  (:meth:`selfcal.calibration.board.deviation.Deviation.drawn_variance`, what the simulator
  draws), the placement's part as the tool point sees it: the base's is removed by the
  alignment; eye-in-hand the tool point rides with the camera (a calibration from images
  locates the camera; the flange sits where the drawing puts it from there), so the hand-eye's
  deviation counts; eye-to-hand it is the flange itself, which the board mount's deviation does
  not move. This is the RMS over the workspace of arms drawn within the deviation (the root of
  the expected mean square); one arm's RMS scatters about it.

``selfcal run`` measures both quantities so: eye-in-hand its validation's "nominal" is the
second (the drawn chain and hand-eye, the point fixed to the camera, after the best rigid
alignment); eye-to-hand its ``flange_centre_aligned_mm`` gives the first. The reference is the
smaller of the two; a plan is predicted to beat it when its prediction is at most
:data:`CLEAR_MARGIN` times that. Units: m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.plan.predict import Directions, predicted_with_held
from selfcal.errors import UsageError
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices

__all__ = ["CLEAR_MARGIN", "NominalReference", "drawn_error", "nominal_reference"]

CLEAR_MARGIN = 0.7
"""A plan beats the reference clearly when its prediction is at most this times the reference:
issue #30 holds a prediction good within 0.7 - 1.4 times the achieved error, so a plan predicted
above 0.7 times the reference may achieve no gain."""


@dataclass(frozen=True)
class NominalReference:
    """The predicted tool-point RMS (m) without calibrating the kinematics (module docstring):
    ``fair_m`` the fair nominal's, ``drawn_m`` the chain's as drawn; ``eye_to_hand`` whether
    the camera stands still and the board rides on the flange (it names the placement);
    ``drawn_why`` when the chain as drawn is no reference, why (its mount is not the one the
    data show: ``selfcal plan --add`` on a robot file without ``[camera_mount]``), else empty."""

    fair_m: float
    drawn_m: float
    eye_to_hand: bool = False
    drawn_why: str = ""

    @property
    def placement(self) -> str:
        """What the fair nominal fits besides the camera, in words."""
        if self.eye_to_hand:
            return "the camera's pose in the base and the board's on the flange"
        return "the hand-eye and the board pose"

    @property
    def best_m(self) -> float:
        """The smaller of the two (the fair nominal's when the chain as drawn is no reference):
        what a calibration has to beat."""
        return self.fair_m if self.drawn_why else min(self.fair_m, self.drawn_m)

    @property
    def what(self) -> str:
        """Which of the two :attr:`best_m` is, in words."""
        if self.drawn_why or self.drawn_m > self.fair_m:
            return "the fair nominal"
        return "the chain as drawn"

    def beaten_by(self, predicted_m: float) -> bool:
        """Whether a calibration predicted at ``predicted_m`` (m) beats the reference clearly
        (at most :data:`CLEAR_MARGIN` times it)."""
        return bool(predicted_m <= CLEAR_MARGIN * self.best_m)

    def to_json(self) -> dict:
        """plan.json's ``nominal`` section (mm)."""
        drawn = ("the chain as drawn at the flange, nothing fitted (the board mount's deviation "
                 "does not move it)" if self.eye_to_hand else
                 "the chain and its camera mount as drawn, nothing fitted (what selfcal run's "
                 "validation calls nominal)")  # fmt: skip
        return {
            "fair_nominal_tool_rms_mm": round(self.fair_m * 1000, 4),
            "drawn_tool_rms_mm": None if self.drawn_why else round(self.drawn_m * 1000, 4),
            "drawn_not_a_reference": self.drawn_why or None,
            "reference": self.what,
            "clear_margin": CLEAR_MARGIN,
            "note": (
                "the tool-point error without calibrating the kinematics, predicted for the same "
                f"postures: fair nominal = the chain at its drawing with {self.placement} and the "
                "camera fitted to the pixels, the chain's deviation less what they "
                f"absorb; drawn = {drawn}; both the RMS over arms drawn within the deviation; "
                "a plan beats the smaller clearly when predicted at most clear_margin times it"
            ),
        }


def drawn_error(G: np.ndarray, variance: np.ndarray) -> float:
    """The chain as drawn (module docstring): ``sqrt(trace(G S))`` (m), ``G`` (k, k) the aligned
    tool weight, ``variance`` (k,) the deviation's (m^2, rad^2)."""
    v = np.asarray(variance, dtype=float)
    if G.shape != (len(v), len(v)):
        raise UsageError(f"shapes do not match: G {G.shape}, variance {v.shape}")
    return float(np.sqrt(max(float(np.einsum("ii,i->", G, v)), 0.0)))


def nominal_reference(
    model: MCPCModel,
    F: np.ndarray,
    G: np.ndarray,
    n_cam: int,
    variance: np.ndarray,
    directions: Directions | None = None,
    *,
    eye_to_hand: bool = False,
    drawn_why: str = "",
) -> NominalReference:
    """Both references (module docstring) for the postures whose information is ``F`` (p, p)
    on ``[camera (n_cam), minimal (k)]``
    (:func:`selfcal.calibration.board.plan.information.frame_information` summed), of the
    calibration's chain ``model``, with the aligned tool weight ``G`` (k, k) and the deviation's
    ``variance`` (k,) of every minimal parameter, the placement's included
    (:meth:`selfcal.calibration.board.deviation.Deviation.drawn_variance`; the fair nominal
    fits the placement, so its part leaves the fair nominal); ``directions`` the model's when
    already computed; ``eye_to_hand`` the mount (:attr:`NominalReference.placement`; its tool
    point, the flange, does not move with the board mount's deviation); ``drawn_why`` why the
    chain as drawn is no reference (:attr:`NominalReference.drawn_why`), empty when it is."""
    dirs = directions or Directions(model)
    place = placement_indices(model.n)
    M = dirs.of(place, np.zeros(0, np.int64))
    inner = np.where(np.isin(minimal_indices(model.joint_types), place), 0.0, variance)
    fair = predicted_with_held(F, G, n_cam, M, inner)
    drawn = drawn_error(G, inner if eye_to_hand else variance)
    return NominalReference(
        fair_m=fair, drawn_m=drawn, eye_to_hand=eye_to_hand, drawn_why=drawn_why
    )
