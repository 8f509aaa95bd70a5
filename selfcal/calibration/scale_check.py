"""Does the target's scale agree with the arm's? A wrong board size or known distance, caught.

A calibration from images takes its scale from the target: the board's square size, or the
field's one known distance. Declared wrong -- a board printed "fit to page", a square measured
in the wrong unit, a distance between the wrong markers -- every camera pose comes out scaled,
the kinematic fit takes the scale into the link lengths, and the reprojection error stays at
the noise floor: the calibration looks perfect and positions the arm a few per cent wrong. The
nominal kinematics know the arm's size to a fraction of a per cent (link lengths are machined
to about a millimetre), so the camera's motion as the target measures it and as the nominal
chain moves it must agree in scale.

:func:`motion_scale` fits ``s T_world_cam ~ B fk(q) C`` over the postures -- the target's
placement ``B`` (world <- base), the hand-eye ``C`` (flange <- camera) and the scale ``s`` free
-- by least squares on each camera pose's origin and axis tips at 0.1 m (the one solver, its
Jacobian by central differences).
``s > 1``: the target measures the motion smaller than the arm makes it (a board printed
larger than declared, a known distance declared too short). :func:`scale_warning` turns a
scale off by more than its tolerance (:data:`SCALE_TOL`, more for an arm that misfits its
nominal) and 5 sigma into a warning that says how large the target really is.

Measured on the synthetic lab of ``tests/integration/test_own_data.py`` (kinematics perturbed
by up to 1 mm and 0.5 deg): s = 0.9992 +- 0.0006 with the right square size, 1.0301 with the
square declared 3 % small, 0.9701 declared 3 % large. The standard deviation is the noise's
alone: the arm's own kinematic errors bias ``s`` by up to 0.4 % (``tests/unit/test_scale_check.py``),
which :data:`SCALE_TOL` leaves room for. Where the postures barely determine the scale (a camera
turned about nearly one point: a scaled motion with a scaled hand-eye fits as well) that bias
grows without bound: the tolerance takes the shift a misfit of the residuals' size can cause
(:attr:`MotionScale.misfit_shift`), and past :data:`SCALE_TOL` the check says it cannot tell
(:func:`scale_unchecked`): on a pan-tilt (1.2-1.5) a board declared at half its size passed.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.errors import SelfCalWarning
from selfcal.kinematics.alignment import AXIS_TIPS, fit_placement_and_hand_eye
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.least_squares import damped_least_squares
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.transforms import pose_from_vec

__all__ = [
    "DISAGREES",
    "SCALE_TOL",
    "UNCHECKED",
    "MotionScale",
    "ScaleUncheckedWarning",
    "ScaleWarning",
    "check_scale",
    "motion_scale",
    "scale_unchecked",
    "scale_warning",
    "scaled_sizes",
]

SCALE_TOL = 0.015
"""Relative scale beyond which the target and the nominal arm disagree (1.5 %): an arm whose every
link is up to 1 mm and 0.5 deg off its nominal shows up to 0.4 % (the KR 6,
``tests/unit/test_scale_check.py``) and 0.6 % (the ER-4u of ``scenarios/paper.toml``, a smaller
arm), a board printed at another scale typically 2-6 %. An arm that misfits its nominal more
widens it (:attr:`MotionScale.tolerance`)."""


DISAGREES = "the target's scale disagrees with the arm's"
"""How :func:`scale_warning` begins (``calibration.json`` keeps it among its ``warnings``)."""

_FD_STEP = 1e-6
"""Central-difference step of the fit's Jacobian (rad of the rotation vectors, m, log scale)."""


UNCHECKED = "the target's scale could not be checked against the arm's"
"""How :func:`scale_unchecked` begins."""


class ScaleWarning(SelfCalWarning):
    """The target's scale and the arm's disagree (:func:`scale_warning`)."""


class ScaleUncheckedWarning(SelfCalWarning):
    """The postures cannot tell the target's scale from the arm's (:func:`scale_unchecked`)."""


@dataclass(frozen=True)
class MotionScale:
    """The scale the nominal arm's motion needs to match the target's camera poses.

    Attributes:
        scale: ``s`` with ``s T_world_cam ~ B fk(q) C`` (1: they agree).
        std: its standard deviation from the fit's residuals.
        rms_m: RMS residual of the fit (m; origin and axis tips), the nominal chain's own misfit.
        spread_m: RMS distance of the camera positions from their centroid (m).
        postures: how many camera poses it used.
        misfit_shift: the relative shift of the scale a misfit of the residuals' size would
            cause along the scale's own direction (the part of the scale's column outside the
            placement's and the hand-eye's): ``|r| / |that part|``. Not a bound: ``r`` is the
            misfit's part the fit left, and its part inside the fitted columns, which is what
            biases the scale, is not bounded by ``|r|``. Large where the postures barely
            determine the scale: a camera turned about nearly one point (a pan-tilt, whose
            axes meet) moves the same as a scaled one with a scaled hand-eye.
    """

    scale: float
    std: float
    rms_m: float
    spread_m: float
    postures: int
    misfit_shift: float = 0.0

    @property
    def tolerance(self) -> float:
        """How far from 1 the scale may be from the arm's own kinematic errors: :data:`SCALE_TOL`,
        four times the nominal chain's misfit over the camera's spread, or
        :attr:`misfit_shift`, whichever is more (past :data:`SCALE_TOL`, said:
        :func:`scale_unchecked`). The last: a 2-joint pan-tilt with a wrist camera
        (tests/integration/test_calibrate_drawn.py's: tests/data/pantilt2.urdf, 12 postures, the
        board as rendered) measured scale 0.473 +- 0.056 from a misfit of 0.04 mm RMS, 9 sigma
        off 1 with nothing wrong but the arm's own deviation from its drawing (the scale's
        column 2e-4 of itself outside the others' span; misfit_shift 1.36)."""
        return max(SCALE_TOL, 4.0 * self.rms_m / max(self.spread_m, 1e-9), self.misfit_shift)


def motion_scale(
    nominal: MCPCModel, q: np.ndarray, T_world_cam: np.ndarray, T_flange_cam: np.ndarray
) -> MotionScale:
    """The scale of the camera poses ``T_world_cam`` (m, 4, 4; m) against the flange poses the
    ``nominal`` chain (no tool) gives at joints ``q`` (m, n) rad; ``T_flange_cam`` (4, 4) m:
    the hand-eye guess to start from (the robot file's camera mount). Needs 3 postures or more.
    """
    T = np.asarray(T_world_cam, dtype=float)
    F = fk_tool(nominal, np.asarray(q, dtype=float))
    B0, C0 = fit_placement_and_hand_eye(T, F, T_flange_cam)

    def residuals(x: np.ndarray) -> np.ndarray:
        Ts = T.copy()
        Ts[:, :3, 3] *= np.exp(x[12])
        return ((pose_from_vec(x[:6]) @ B0 @ F @ C0 @ pose_from_vec(x[6:12]) - Ts) @ AXIS_TIPS)[
            :, :3
        ].ravel()

    def jacobian(x: np.ndarray) -> np.ndarray:
        h = _FD_STEP
        return np.stack([(residuals(x + e) - residuals(x - e)) / (2 * h) for e in h * np.eye(13)],
                        axis=1)  # fmt: skip

    x, r, _ = damped_least_squares(residuals, jacobian, np.zeros(13), None, max_iter=100)
    dof = max(r.size - 13, 1)
    s2 = float(r @ r) / dof
    J = jacobian(x)
    inv = max(float(np.linalg.pinv(J.T @ J)[12, 12]), 0.0)  # 1 / |the column outside the rest|^2
    s = float(np.exp(x[12]))
    P = T[:, :3, 3]
    spread = float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))
    rms = float(np.sqrt(np.mean(r**2)))
    shift = float(np.linalg.norm(r) * np.sqrt(inv))  # relative: the column is d r / d log s
    return MotionScale(s, s * float(np.sqrt(inv * s2)), rms, spread, len(T), shift)


def scale_warning(
    ms: MotionScale, robot: str, target: str, correct: str, *, failed: bool = False
) -> str | None:
    """A warning when ``ms`` is off by more than its tolerance and 5 sigma, else None.
    ``robot``: the robot's name; ``target``: what set the scale (e.g. "the chessboard of
    board.toml (square_mm = 15.0)"); ``correct``: the fix, given the scale (e.g. "square_mm =
    15.45 would match the arm"); ``failed``: the calibration failed, so it took nothing into
    the link lengths (the cause of a failed fit, not a warning about its result)."""
    off = ms.scale - 1.0
    if abs(off) <= ms.tolerance or abs(off) <= 5 * ms.std:
        return None
    measured = abs(1.0 / ms.scale - 1.0)  # the target's motion against the arm's
    taken = ("the calibration cannot fit both" if failed else
             "the calibration has taken this into the link lengths, so its positions are about "
             f"{measured * 100:.1f} % off")  # fmt: skip
    return (
        f"{DISAGREES}: {target} measures the camera's motion "
        f"{measured * 100:.1f} % {'smaller' if off > 0 else 'larger'} than the nominal "
        f"kinematics of {robot} make it (scale {ms.scale:.4f} +- {ms.std:.4f} over "
        f"{ms.postures} postures); {taken}. A target printed or measured at "
        f"another size does this ({correct}), as does a --robot that is not this arm"
    )


def scale_unchecked(ms: MotionScale, target: str) -> str | None:
    """What the user is told when ``ms``'s postures cannot tell the target's scale from the
    arm's (:attr:`MotionScale.misfit_shift` above :data:`SCALE_TOL`: a scaled motion with a
    scaled hand-eye fits them about as well, and a target declared at half its size passes the
    tolerance), else None; ``target``: what set the scale (as :func:`scale_warning`'s)."""
    if ms.misfit_shift <= SCALE_TOL:
        return None
    return (
        f"{UNCHECKED}: a scaled motion with a scaled hand-eye fits the camera's motion over "
        f"the {ms.postures} postures nearly as well (a camera turned about nearly one point, "
        "as a pan-tilt's meeting axes turn it), so only a scale off by more than "
        f"{ms.tolerance * 100:.0f} % would be caught "
        f"(scale {ms.scale:.3f} +- {ms.std:.3f}). Measure {target} by hand, or add postures "
        "that move the camera along, not only turn it (a camera mounted off the axes, an arm "
        "whose axes do not meet)"
    )


def scaled_sizes(sizes: dict[str, float], scale: float) -> str:
    """``"square_mm = 15.45, marker_mm = 11.59"``: the lengths of a target description (its
    keys ending in ``_mm``) times ``scale``, the sizes that would match the arm."""
    return ", ".join(f"{k} = {v * scale:.4g}" for k, v in sizes.items() if k.endswith("_mm"))


def check_scale(
    robot,
    q: np.ndarray,
    T_world_cam: np.ndarray,
    target: str,
    correct: Callable[[float], str],
    *,
    T_flange_tool: np.ndarray | None = None,
) -> list[str]:
    """The scale check of a calibration: :func:`motion_scale` of ``robot``'s nominal chain (a
    :class:`selfcal.robot.definition.RobotDef`, its camera mount the hand-eye start) against the camera
    poses ``T_world_cam`` (m, 4, 4) at joints ``q`` (m, n) rad, and beyond the tolerance a
    :class:`ScaleWarning` (also returned, for ``calibration.json``; else ``[]``). ``target`` and
    ``correct(scale)``: the texts of :func:`scale_warning`. ``T_flange_tool``: the chain's tool
    on the flange to start from instead of the camera mount (eye-to-hand: the board's mount,
    ``T_world_cam`` then the board's poses in the camera frame). Where the postures cannot
    tell the scale, a :class:`ScaleUncheckedWarning` says so instead (:func:`scale_unchecked`;
    also returned)."""
    start = robot.T_flange_cam if T_flange_tool is None else T_flange_tool
    ms = motion_scale(nominal_mcpc(robot), q, T_world_cam, start)
    text = scale_warning(ms, robot.name, target, correct(ms.scale))
    if text is not None:
        warnings.warn(text, ScaleWarning, stacklevel=3)
        return [text]
    unchecked = scale_unchecked(ms, target)
    if unchecked is None:
        return []
    warnings.warn(unchecked, ScaleUncheckedWarning, stacklevel=3)
    return [unchecked]
