"""Robot calibration with a board of known geometry: camera, hand-eye and kinematics.

The known-board counterpart of the self-calibration route (one camera on the flange, a board
somewhere in the scene):

1. :func:`selfcal.calibration.board.calibrate.calibrate_board` -- the camera and the board pose of every frame
   (Zhang via ``cv2.calibrateCamera``, then the bundle adjustment with the board held);
2. the fair nominal (:mod:`selfcal.calibration.board.nominal_fit`): the nominal chain with board pose, hand-eye and
   cameras fitted to the pixels -- the reference every result is judged against, and the start
   of every further fit;
3. :func:`selfcal.calibration.identify.identify` -- the two-stage method of the paper on the camera poses, a
   check of the data (its failure on a small set is noted, not fatal: the fits start from the
   fair nominal; its warnings are silenced: its model is not used, and a failure only triggers
   the check of the rows' pairing with the images);
4. the kinematic parameters the data support (:mod:`selfcal.calibration.board.param_selection`: rank and
   conditioning of the identification Jacobian, then leave-one-configuration-out
   cross-validation between nested candidates), each candidate the one-step refinement of
   :mod:`selfcal.calibration.board.refine`: the same bundle adjustment with the camera poses taken from the
   kinematic chain and the board's points held at their declared positions. The board fixes the
   world frame (the board frame) and the scale, so no parameter is held for a gauge and no
   known distance is needed. With a rig of N >= 2 cameras
   (:func:`selfcal.calibration.board.rig.calibrate_board_rig` gives its start) every further camera's pixels
   join the same adjustment: its own model and free parameters, its pose in the first camera's
   frame (``T_first_cam``) estimated with the kinematics (the robot's tool is the first
   camera). With ``joint_sigma`` (e.g. the encoder quantisation,
   :func:`selfcal.estimation.joint_report.encoder_sigma`) every frame gets joint corrections with
   a zero-mean Gaussian prior (errors in variables, as :mod:`selfcal.calibration.field.joint_refine` explains);
   without, the read-back is taken as exact.

Measurement terms (``terms``: touch-probe points, tracker rows, :mod:`selfcal.terms`) join every
fit of steps 2 and 4 -- the fair nominal with their own unknowns, every candidate and fold --
on the chain as :mod:`selfcal.calibration.board.terms` presents it; the folds leave out images
only.

The model is written in the MCPC gauge with the nominal's joint offsets
(:func:`selfcal.calibration.board.nominal_fit.standard_gauge`), so its minimal parameters compare one to one.

Eye-to-hand (``eye_to_hand=True``: the cameras static in the cell, the board on the flange) is
the same route on the inverted chain: the model's world is the first camera and its tool the
board, so its placement is base -> camera (``V_0``) and flange -> board (``V_n``), and the
camera poses of the camera stage enter as the board's poses in the camera frame
(:class:`selfcal.estimation.kinematic_poses.KinematicPoses`); the selection, the fair nominal
and the refinement are unchanged.

Frames: the world is the board frame (m); the model's tool is the OpenCV camera frame (eye-to-hand:
the world is the first camera's OpenCV frame, the tool the board frame). SI units.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.calibrate import BoardCalibration, calibrate_board
from selfcal.calibration.board.nominal_fit import fit_nominal, standard_gauge
from selfcal.calibration.board.param_selection import (
    Selection,
    held_selection,
    select_parameters,
)
from selfcal.calibration.board.refine import BoardObservations, Refinement
from selfcal.calibration.board.rig import BoardRigCalibration
from selfcal.calibration.identify import (
    IdentificationError,
    IdentificationResult,
    IdentificationWarning,
    identify,
)
from selfcal.camera import CameraModel, Pinhole
from selfcal.errors import InputError, UsageError
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.terms.base import Term, check_terms

__all__ = ["BoardRobotCalibration", "calibrate_robot_with_board"]


@dataclass
class BoardRobotCalibration:
    """Result of :func:`calibrate_robot_with_board`: the refined kinematic ``model`` (world =
    board frame, tool = camera) and ``camera``; ``camera_std`` of its free parameters; the stages
    it started from (``board``: the camera stage, ``identification``: the two-stage model, None
    when it failed: ``identification_error`` says why); ``used`` (m,) the frames in the
    adjustment; ``rms_px`` the final reprojection RMS (2-D, every camera's inliers); ``held``:
    the kinematic parameters held (``selection`` says why: rank, conditioning or
    cross-validation, :mod:`selfcal.calibration.board.param_selection`); ``nominal``: the fair nominal
    (:mod:`selfcal.calibration.board.nominal_fit`).
    ``cameras``, ``cameras_std``: every camera of the rig (the first is ``camera``);
    ``T_first_cam`` (N, 4, 4): every camera's pose in the first camera's frame (m; the first
    the identity). ``sections``: the measurement terms' ``calibration.json`` sections of the
    chosen fit (:mod:`selfcal.calibration.board.terms`)."""

    model: MCPCModel
    camera: CameraModel
    camera_std: dict[str, float]
    board: BoardCalibration
    identification: IdentificationResult | None
    used: np.ndarray
    rms_px: float
    held: tuple[str, ...]
    cameras: tuple[CameraModel, ...] = ()
    cameras_std: tuple[dict[str, float], ...] = ()
    T_first_cam: np.ndarray = field(default_factory=lambda: np.eye(4)[None])
    nominal: Refinement | None = None
    selection: Selection | None = None
    identification_error: str | None = None
    sections: tuple = ()


def calibrate_robot_with_board(
    board: Board,
    features: Sequence[Features],
    q: np.ndarray,
    nominal: MCPCModel,
    width: int,
    height: int,
    *,
    free: Sequence[str] = ("fx", "mu", "cx", "cy"),
    model: str = "pinhole",
    names: Sequence[str] | None = None,
    joint_sigma: float | np.ndarray | None = None,
    rig: BoardRigCalibration | None = None,
    rig_features: Sequence[Sequence[Features]] = (),
    max_iter: int = 100,
    initial: Pinhole | None = None,
    eye_to_hand: bool = False,
    terms: Sequence[Term] = (),
    keep: Sequence[str] | None = None,
) -> BoardRobotCalibration:
    """Calibrate the camera and the robot from the board ``features`` of one camera image per
    frame and the joint read-backs ``q`` (m, n) rad; ``model``, ``free``: the camera model
    (:data:`selfcal.camera.MODELS`) and its parameters to estimate (OpenCV names; with a lens the
    refinement adjusts its coefficients too); ``nominal``: the nominal MCPC model with the
    camera as tool (its world frame need not be the board's); ``joint_sigma`` (rad / m, scalar
    or (n,)): the read-back's standard deviation, or None for exact read-back; ``initial``: a
    camera to start from (:func:`selfcal.calibration.board.calibrate.calibrate_board`). ``rig``: the board
    calibration of a rig of N >= 2 cameras whose first camera took ``features`` (the start of
    every further camera and its extrinsics), ``rig_features[c - 1]`` camera ``c``'s features,
    one per frame in the frames' order. ``eye_to_hand``: the cameras are static and the board
    rides on the flange; ``nominal``'s tool is then the board at its nominal mount (any: the
    fair nominal fits it) and the model returned has world = the first camera, tool = the board.
    ``terms``: further measurements of the same robot (:mod:`selfcal.terms`) estimated with the
    images in every fit, the fair nominal's too (their context:
    :mod:`selfcal.calibration.board.terms`). ``keep``: the kinematic parameters to fit (another
    calibration's chosen ones, e.g. a bootstrap refit's) instead of running the selection
    (:func:`selfcal.calibration.board.param_selection.held_selection`); None: select them. See
    the module docstring.

    Raises:
        selfcal.calibration.board.calibrate.BoardInputError / BoardMismatchError: as :func:`calibrate_board`.
        InputError: two terms of one kind, or a term's data that do not fit the chain.
        EstimationError: not even the fair nominal could be fitted (the selection's other
            candidates that fail are noted and left out), or the fit of ``keep`` failed.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    check_terms(terms)
    if len(q) != len(features):
        raise InputError(f"{len(features)} images but {len(q)} joint rows; give one row per image")
    cam_stage = calibrate_board(board, features, width, height, free=free, model=model, names=names,
                                initial=initial)  # fmt: skip
    n_cams = 1 if rig is None else len(rig.cameras)
    if len(rig_features) != n_cams - 1:
        raise UsageError(f"a rig of {n_cams} cameras needs {n_cams - 1} further feature lists")
    obs = BoardObservations(board, cam_stage, features, q, rig, rig_features, joint_sigma,
                            eye_to_hand, tuple(terms))  # fmt: skip
    used = cam_stage.used.copy()
    nominal_fit = fit_nominal(obs, nominal)
    ident, ident_error = None, None
    try:  # the two-stage identification: a check of the data (and the Monte Carlo's comparison)
        with warnings.catch_warnings():  # its model is not used: what it held or how well it
            warnings.simplefilter("ignore", IdentificationWarning)  # fitted is no finding
            ident = identify(nominal, q[used], obs.tool_poses()[used])
    except IdentificationError as exc:
        ident_error = exc.message
    if keep is None:
        selection = select_parameters(obs, nominal_fit.model, max_iter=max_iter)
        # the nominal chosen: the calibration IS the fair nominal (the same numbers, not a refit
        # that differs in the ninth digit and reads as a gain)
        fit = nominal_fit if selection.chosen == 0 else selection.fit
    else:
        selection = held_selection(obs, nominal_fit.model, tuple(keep), max_iter=max_iter)
        fit = selection.fit
    return BoardRobotCalibration(
        model=standard_gauge(fit.model, nominal_fit.model.joint_offsets),
        camera=fit.cameras[0],
        camera_std=fit.cameras_std[0],
        board=cam_stage,
        identification=ident,
        used=used,
        rms_px=fit.rms_px,
        held=tuple(selection.held),
        cameras=fit.cameras,
        cameras_std=fit.cameras_std,
        T_first_cam=fit.T_first_cam,
        nominal=nominal_fit,
        selection=selection,
        identification_error=ident_error,
        sections=fit.sections,
    )
