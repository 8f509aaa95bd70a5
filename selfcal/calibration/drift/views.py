"""One new view of the board linearised at a board calibration (the drift check, issue #29).

The pixels the calibration predicts for it from the joints alone, their derivatives by every
change the check considers (the estimated parameters, the camera, the chain's tool and world,
each joint's offset) and the view's own covariance (the model error, the joint read-back and
the corner noise): :mod:`selfcal.calibration.drift.images` stacks them, tests them and
:mod:`selfcal.calibration.drift.attribution` fits the changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.board.misfit import board_view, tip_map
from selfcal.calibration.board.view_jitter import camera_directions, view_jitter_from_json
from selfcal.calibration.drift.p_value import chi2_isf
from selfcal.camera import CameraModel
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.transforms import adjoint, inv_pose

__all__ = [
    "ViewJacobians",
    "ViewNoise",
    "calibration_views",
    "tool_pose_error",
    "MIN_WHITE_DOF",
    "WHITE_LEVEL",
    "white_level",
    "view_jacobians",
    "view_noise",
    "view_white_px",
    "span_basis",
]

MIN_WHITE_DOF = 30
"""The fewest degrees of freedom (a view's pixels outside its pose span and the camera's
directions) from which :func:`view_white_px` estimates a view's own white corner noise (its
relative standard error ``sqrt(2 / dof)``: 26 % here, 11 % for a board of 88 corners)."""
WHITE_LEVEL = 0.01
"""A view's own white noise replaces the calibration's only where it is above it at this level
(its squared sum there beyond the calibration's chi-square quantile): taken wherever larger, it
is larger in half the views of the calibration's own noise by chance and the check spends less
than its alpha (in tests/unit/test_drift_view_noise.py's scene 6 false alarms of 60 at alpha 0.2
where the assumed covariance gives 9), which is power lost. The level is the whole check's:
each of its ``n`` views is held to ``WHITE_LEVEL / n`` (:func:`white_level`), since a view
tested with its own noise makes the check's verdict "cannot tell" at best, so an unchanged arm
imaged with the calibration's noise is called noisy in at most 1 % of checks (at 1 % a view, 5 %
of five-view checks)."""


def white_level(n_views: int) -> float:
    """The level at which each of a check's ``n_views`` new views is called noisier than the
    calibration (:data:`WHITE_LEVEL` shared among them, Bonferroni)."""
    return WHITE_LEVEL / max(1, int(n_views))


@dataclass(frozen=True)
class ViewJacobians:
    """One view linearised at the calibration (px; derivatives per m and rad).

    Attributes:
        r: (2k,) detected - predicted pixels.
        local: (2k, 2k) its own covariance (model error, per-view misfit in the pose span and
            the camera's directions, joint read-back and corner noise).
        kin: (2k, p) derivative by the estimated kinematic parameters; cam: (2k, c) by the
            camera's free parameters.
        tool: (2k, 6) by a body twist of the chain's tool (eye-in-hand the camera on the
            flange, eye-to-hand the board on it); world: (2k, 6) by a twist of the chain's
            world frame (the board, eye-to-hand the camera); joints: (2k, n) by each joint's
            offset.
        B: (6, 6) the map of a body twist of the chain's tool to the move of the tool point
            (the flange) and the rotation, world frame; Ad: (6, 6) of a world twist to a body
            twist; tw: (6, n) every joint's body twist.
        paired: ``r`` is the difference from the calibration's own frame at the same posture
            (:mod:`selfcal.calibration.drift.paired`): the calibration's estimate cancels in
            it (no ``H C H^T`` term of its own) and ``local`` is both views' noise.
        frame: a paired view's frame, ``(key, rows, noise)``: the frame's index among the
            calibration's, the rows (2k,) of its pixels ``r`` subtracts and the frame's noise
            (2K, 2K) px^2 over all its pixels: two views paired with one frame share its noise
            on their common rows (``Cov(d1, d2) = noise[rows1, rows2]``); None otherwise.
        frame_H: a paired view's frame's ``[kin, cam]`` on those rows (2k, p + c): its noise
            moved the calibration's estimate, so the difference shares ``H_b C_e H_u^T`` with
            every other new view's residuals (``C_e`` the estimate's covariance from the noise,
            :func:`selfcal.calibration.drift.covariance.view_covariance`); None otherwise.
        own_px: ``(own, calibration's)`` the view's own white corner noise (px) where it
            replaced the calibration's (:func:`view_white_px`, ``own_white``) and the
            calibration's white noise it was above (``white_px`` of :func:`view_jacobians`);
            None where the calibration's is used. Such a view never
            gives "unchanged" (:mod:`selfcal.calibration.drift.noisy`).
        frame_px: a paired view's ``(frame's, calibration's)`` white corner noise (px) where
            its frame, the calibration's own image at that posture, shows more than the
            calibration's (:func:`selfcal.calibration.drift.paired.pair_views`): the
            difference's excess is (also) that image's, named as such; None otherwise.
    """

    r: np.ndarray
    local: np.ndarray
    kin: np.ndarray
    cam: np.ndarray
    tool: np.ndarray
    world: np.ndarray
    joints: np.ndarray
    B: np.ndarray
    Ad: np.ndarray
    tw: np.ndarray
    paired: bool = False
    frame: tuple[int, np.ndarray, np.ndarray] | None = None
    frame_H: np.ndarray | None = None
    own_px: tuple[float, float] | None = None
    frame_px: tuple[float, float] | None = None


def span_basis(M: np.ndarray) -> np.ndarray:
    """(r, q) an orthonormal basis of the span of the columns ``M`` (r, c) (a view's pose and
    camera columns, px): its left singular vectors above ``1e-9`` of the largest singular
    value; (r, 0) for a zero or empty ``M``."""
    Q, s, _ = np.linalg.svd(M, full_matrices=False)
    return Q[:, s > 1e-9 * s[0]] if s.size and s[0] > 0 else Q[:, :0]


def view_white_px(r: np.ndarray, A: np.ndarray, Jc: np.ndarray, than_px: float = 0.0,
                  level: float = WHITE_LEVEL) -> float | None:  # fmt: skip
    """The white corner noise (px) a view's own residuals ``r`` (2k,) px show outside the span
    of its pose columns ``A`` (2k, 6) and its camera columns ``Jc`` (2k, c): their RMS over the
    ``2k - rank`` degrees of freedom there, which no change the drift check considers (every
    kinematic one moves the pixels in the pose span, the camera's in its columns) and no
    estimation error reaches; None below :data:`MIN_WHITE_DOF` of them, or where it is not
    above ``than_px`` (the calibration's white noise) at ``level`` (a check's views:
    :func:`white_level`).

    Real images differ in their corner noise (blur, focus, the board's angle: the real mecheye
    set's group 2 shows 0.126 and 0.118 px there in two of its images where the calibration's
    white noise is 0.078 px, ``python -m selfcal.benchmarks.drift.real_folds``), so one white
    noise for every new view is wrong for some of them; in this span a view measures its
    own."""
    Q = span_basis(np.concatenate([A, Jc], axis=1))
    dof = len(r) - Q.shape[1]
    if dof < MIN_WHITE_DOF:
        return None
    e = r - Q @ (Q.T @ r)
    if e @ e <= than_px**2 * chi2_isf(level, dof):
        return None
    return float(np.sqrt(e @ e / dof))


def tool_pose_error(A: np.ndarray, B: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """(2k, 2k) px^2 a view's covariance from an error of the tool pose with the variances
    ``m2`` (6,) per tool-point coordinate (m^2) and rotation coordinate (rad^2), world frame:
    ``A`` (2k, 6) the pixels' derivative by a body twist of the chain's tool, ``B`` (6, 6) its
    map to the tool point's move and rotation (:class:`ViewJacobians`)."""
    tip = A @ np.linalg.inv(B)  # pixels by a move of the tool point and a rotation (world)
    return (tip * m2) @ tip.T


def view_jacobians(em: ToolErrorModel, camera: CameraModel, q: np.ndarray, X: np.ndarray,
                   uv: np.ndarray, *, eye_to_hand: bool, pixel_sigma_px: float,
                   joint_sigma_rad: np.ndarray | None,
                   jitter: np.ndarray | None = None, camera_misfit_px: float = 0.0,
                   pose_misfit_px: float = 0.0, own_white: bool = False,
                   white_level: float = WHITE_LEVEL,
                   white_px: float | None = None) -> ViewJacobians:  # fmt: skip
    """The view of board points ``X`` (k, 3) (board frame, m) detected at ``uv`` (k, 2) px by
    ``camera`` at the joints ``q`` (n,) rad / m, linearised at the calibration ``em`` (its
    chain, estimated columns and model error) with the corner noise ``pixel_sigma_px``, the
    joint read-back noise ``joint_sigma_rad`` (n,) or None and the per-view jitter ``jitter``
    (6, 6) of the chain's tool pose (body twist, m and rad;
    :mod:`selfcal.calibration.board.view_jitter`) or None, with its per-view misfit
    ``camera_misfit_px`` (px) in each of the camera's directions the pose cannot mimic, and
    ``pose_misfit_px`` (px) in each direction of the view's pose span (orthonormal, in pixels:
    what the calibration's frames carry there when it is known, in place of ``jitter``).
    ``own_white``: the corner noise is the view's own where it is above the calibration's
    white noise ``white_px`` (px; default ``pixel_sigma_px``: :func:`view_white_px`, where it
    has the degrees of freedom): an image noisier than the calibration's frames is not read as
    a change, nor as no change (``own_px``); ``white_level`` that test's level."""
    model = em.model
    T = fk_tool(model, q[None])[0]
    _, uv_hat, A, Jc = board_view(camera, T, X, eye_to_hand)
    t = np.zeros(3) if em.T_tool_point is None else np.asarray(em.T_tool_point)[:3, 3]
    B = tip_map(T, t)
    rot = 0.0 if em.model_error_rad is None else em.model_error_rad
    m2 = np.r_[np.full(3, em.model_error_m**2), np.full(3, rot**2)] * em.model_error_factor(q)[0]
    tw = joint_twists(model, q[None])[0]
    joints = A @ tw
    Ad = adjoint(inv_pose(T))
    r = (np.asarray(uv, float) - uv_hat).reshape(-1)
    cam = Jc.reshape(len(A), -1)
    than = pixel_sigma_px if white_px is None else float(white_px)
    own = view_white_px(r, A, cam, than, white_level) if own_white else None
    white = pixel_sigma_px if own is None else own
    local = tool_pose_error(A, B, m2) + white**2 * np.eye(len(A))
    if jitter is not None:
        local += A @ np.asarray(jitter, float) @ A.T
    if pose_misfit_px > 0.0:
        local += pose_misfit_px**2 * (A @ np.linalg.pinv(A))
    if camera_misfit_px > 0.0:
        U = camera_directions(A, cam)
        local += camera_misfit_px**2 * (U @ U.T)
    if joint_sigma_rad is not None:
        local += (joints * np.asarray(joint_sigma_rad, float) ** 2) @ joints.T
    return ViewJacobians(
        r=r,
        local=local,
        kin=A @ identification_jacobian(model, q[None])[0][:, em.columns],
        cam=cam,
        tool=A,
        world=A @ Ad,
        joints=joints,
        B=B,
        Ad=Ad,
        tw=tw,
        own_px=None if own is None else (own, than),
    )


@dataclass(frozen=True)
class ViewNoise:
    """A calibration's noise levels for new views (:func:`view_noise`): the white corner noise
    ``pixel_sigma_px`` (px), the joint read-back ``joint_sigma_rad`` (n,) or None, the per-view
    pose ``jitter`` (6, 6) (m, rad) or None (a file written before ``pose_misfit_px``), the
    misfit per camera direction ``camera_misfit_px`` (px) and per direction of a view's pose
    span ``pose_misfit_px`` (px; 0 where ``jitter`` is used or nothing is counted); ``white_px``
    (px): the calibration's own frames' white corner noise outside their pose spans and the
    camera's directions (the ``accuracy`` block's ``view_jitter.white_px``), against which a
    new view's, measured there (:func:`view_white_px`), is tested; None (a file written before
    it): ``pixel_sigma_px``."""

    pixel_sigma_px: float
    joint_sigma_rad: np.ndarray | None
    jitter: np.ndarray | None
    camera_misfit_px: float
    pose_misfit_px: float = 0.0
    white_px: float | None = None

    @property
    def misfit_counted(self) -> bool:
        """Did the calibration's own frames show a per-view misfit beyond the corner noise (what
        :mod:`selfcal.calibration.drift.paired` cancels at their postures)?"""
        return self.jitter is not None or self.pose_misfit_px > 0 or self.camera_misfit_px > 0


def view_noise(cal: BoardCalibrationResult, where: str = "calibration.json") -> ViewNoise:
    """The noise the check gives each new view of the calibration ``cal``: its bounds' corner and
    joint noise and, when its own frames showed a per-view misfit (``accuracy.view_jitter``
    counted), that jitter (or its misfit per pose direction, where the block gives one), its
    camera misfit and its white corner noise in place of the bounds' (which holds the misfit's
    energy: :mod:`selfcal.calibration.board.view_jitter`); a file written before the white
    noise keeps the bounds' noise. ``where`` the calibration's file, for the
    error a malformed block raises.

    A new view's own white noise is tested against the frames' white noise (``white_px``)
    whether or not the misfit is counted: the same statistic over the same pixels, which no
    fitted unknown reaches, while the bounds' noise is the final fit's RMS corrected for its
    parameters alone, low where the frames' joint read-back corrections are estimated with them
    (they absorb part of the noise in each frame's pose span): against it an unchanged arm's
    views were called noisy more often than the level (docs/tool-accuracy.md, the drift check's
    'cannot tell').

    Raises:
        InputError: the accuracy block's ``view_jitter`` is malformed (names ``where``).
    """
    assert cal.bounds is not None
    js = cal.bounds.joint_sigma_deg
    js_rad = None if js is None else np.radians(np.asarray(js, float))
    found = view_jitter_from_json(cal.accuracy, where)
    if found is None or not found.counted:
        white = None if found is None else found.white_px
        return ViewNoise(cal.bounds.pixel_sigma_px, js_rad, None, 0.0, white_px=white)
    if found.white_px is None:
        return ViewNoise(cal.bounds.pixel_sigma_px, js_rad, found.covariance, 0.0)
    cam = found.camera_misfit_px or 0.0
    if found.pose_misfit_px is None:  # written before it: the jitter's mean carried to the view
        return ViewNoise(found.white_px, js_rad, found.covariance, cam, white_px=found.white_px)
    return ViewNoise(found.white_px, js_rad, None, cam, found.pose_misfit_px, found.white_px)


def calibration_views(cal: BoardCalibrationResult, em: ToolErrorModel, q: np.ndarray,
                      views: list[tuple[int, np.ndarray, np.ndarray]], *,
                      where: str = "calibration.json") -> list[ViewJacobians]:  # fmt: skip
    """The first camera's ``views`` (frame ``f`` into ``q`` (m, n) rad / m, board points ``X``
    (k, 3) m, detected ``uv`` (k, 2) px) linearised at the calibration ``cal`` (``em`` its
    error model) with its noise (:func:`view_noise`); ``where`` the calibration's file, for the
    error a malformed block raises.

    Raises:
        InputError: the accuracy block's ``view_jitter`` is malformed (names ``where``).
    """
    noise = view_noise(cal, where)
    return [view_jacobians(em, cal.cameras[0], q[f], X, uv, eye_to_hand=cal.eye_to_hand,
                           pixel_sigma_px=noise.pixel_sigma_px,
                           joint_sigma_rad=noise.joint_sigma_rad, jitter=noise.jitter,
                           camera_misfit_px=noise.camera_misfit_px,
                           pose_misfit_px=noise.pose_misfit_px, own_white=True,
                           white_level=white_level(len(views)), white_px=noise.white_px)
            for f, X, uv in views]  # fmt: skip
