"""The fair nominal of a board calibration: the nominal chain with only its placement fitted.

"Nominal" is the robot file's kinematic chain with everything but the kinematics fitted by the
same objective as the calibration: the board pose (board <- base, 6 dof), the hand-eye (flange
<- camera, 6 dof) and every camera's free parameters, fitted to the reprojection of the same
features with the same loss on the one solver (:func:`selfcal.calibration.board.refine.refine_on_board` with
the placement parameters free and every chain parameter held). A calibration is judged against
this model -- what the robot gives without calibrating its kinematics -- never against a
pose-distance proxy. The start of that fit is the closed-form placement of the nominal chain on
the camera stage's poses (:func:`place_nominal`).

Frames and units: world = board frame (m), the model's tool = the first camera (OpenCV frame);
eye-to-hand (the board on the flange) world = the first camera, tool = the board, and the
placement is base -> camera and flange -> board.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np

from selfcal.calibration.board.refine import BoardObservations, Refinement, refine_on_board
from selfcal.kinematics.alignment import AXIS_TIPS, fit_placement_and_hand_eye, regauge
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, chain_transforms
from selfcal.transforms import make_pose

__all__ = [
    "FAIR_NOMINAL_ITERATIONS",
    "beyond_placement",
    "fit_nominal",
    "place_nominal",
    "placement",
    "placement_indices",
    "standard_gauge",
]

FAIR_NOMINAL_ITERATIONS = 400
"""The fair nominal's budget of Levenberg-Marquardt iterations (the route's other fits have 100).
Its residuals hold the arm's deviation from its drawing by construction (the chain is held),
and it starts from the closed-form placement: Gauss-Newton converges only linearly on such a
large-residual problem along its weakest direction: the camera's rotation against its principal
point (a turn about the optical x / y axis moves the image as cy / cx do; the column-scaled
information, its condition number 3e5 - 5e5 on the greedy and the exchanged plan alike, has
those pairs as its two weakest directions). The deviation
drives the principal point up to 62 px from the camera stage's value along it. Measured on 24
replays (``selfcal run`` of the slow CLI test's eye-to-hand plans of 10 of 200 candidates,
greedy and exchanged, ``[perturbation] seed`` 1 - 6, analytic and rendered; the fit rerun with
2000 iterations): 23 converged in 10 - 58 iterations, the exchanged plan's rendered seed 1 in
101, its cost at 90 iterations 2e-5 above the optimum (a chi-square of 4e-5: within the data's
own uncertainty, but not the solver's tolerance). Four times the worst measured; a fit that
still does not converge fails and says what was tried. The selection's candidates (the
placement-only one and the folds included) hold the chain too, but start from this fit's
result, not from the placement: they keep the 100."""


def placement_indices(n: int) -> np.ndarray:
    """Flat MCPC indices of the placement: all six parameters of ``V_0`` (world -> joint 1: the
    board pose) and of ``V_n`` (last joint -> camera: the hand-eye) of a chain of ``n`` joints;
    together they move the nominal chain rigidly in the world and the camera on the flange
    (12 dof), the chain itself held."""
    return np.r_[np.arange(6), 6 * n + np.arange(6)]


def beyond_placement(free_idx: np.ndarray, offset_joints: np.ndarray, n: int) -> int:
    """How many kinematic parameters a board calibration of a chain of ``n`` joints estimates
    beyond its placement (:func:`placement_indices`, always estimated): the flat MCPC indices
    ``free_idx`` that are not the placement's and the zero offsets of the joints
    ``offset_joints``. The one count ``selfcal calibrate``'s line, ``selfcal plan``'s and
    ``selfcal plan --add``'s give (``--add`` counted the placement's 12 where ``calibrate``
    did not: "14 ... beyond the placement identified" against "estimated 26 -> 26")."""
    return int(np.setdiff1d(free_idx, placement_indices(n)).size + len(offset_joints))


def _turns() -> np.ndarray:
    """(24, 4, 4) the proper rotations that map the axes onto the axes (signed permutations of
    determinant +1): the starts of :func:`placement` when the mount is unknown."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            R[range(3), perm] = signs
            if np.linalg.det(R) > 0:
                out.append(make_pose(R, np.zeros(3)))
    return np.array(out)


def placement(
    F: np.ndarray, T: np.ndarray, *, any_mount: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """``(B, C)`` with ``B @ F[i] @ C ~ T[i]`` for the chain's tool poses ``F`` (m, 4, 4) and the
    measured ones ``T`` (m): alternating closed-form rigid fits
    (:func:`selfcal.kinematics.alignment.fit_placement_and_hand_eye`, each round lowering the
    misfit of the axis tips) from ``C`` = the identity. ``any_mount``: the mount is unknown
    (eye-to-hand: a board on the flange any way round), so the alternation starts from each of
    the 24 quarter-turn rotations as well and the best fit wins (each descent ends in a local
    minimum of the misfit, not necessarily the least)."""
    starts = _turns() if any_mount else np.eye(4)[None]
    B, C = fit_placement_and_hand_eye(T, F, starts)  # each start descends on its own
    misfit = np.sum(((B[:, None] @ F @ C[:, None] - T) @ AXIS_TIPS)[..., :3, :] ** 2,
                    axis=(1, 2, 3))  # fmt: skip
    best = int(np.argmin(misfit))  # the first of the least
    return B[best], C[best]


def place_nominal(nominal: MCPCModel, q: np.ndarray, T_board_cam: np.ndarray, *,
                  any_mount: bool = False) -> MCPCModel:  # fmt: skip
    """``nominal`` (tool = the camera at its nominal mount) placed on the camera poses
    ``T_board_cam`` (m, 4, 4) at the joints ``q`` (m, n) rad (eye-to-hand: the tool the board,
    the poses the board's in the camera frame, ``any_mount``): board pose and hand-eye by
    :func:`placement` from the nominal mount -- the start of :func:`fit_nominal`."""
    B, C = placement(fk_tool(nominal, q), T_board_cam, any_mount=any_mount)
    return nominal.with_base(B).with_tool(C)


def standard_gauge(model: MCPCModel, offsets: np.ndarray) -> MCPCModel:
    """The same chain (same tool pose at every joint vector) in the MCPC gauge
    (:func:`selfcal.kinematics.mcpc.gauge_fix`) with the joint offsets ``offsets`` (n,) rad: a fit that
    freed a whole ``V_0`` or a joint's zero offset written as the minimal parameters, so that it
    compares one to one with models in that gauge."""
    return regauge(chain_transforms(model), model.joint_types, offsets)


def fit_nominal(obs: BoardObservations, nominal: MCPCModel, *, stds: bool = True) -> Refinement:
    """The fair nominal (module docstring) from the observations ``obs`` of every frame with the
    board; its model in the MCPC gauge with ``nominal``'s joint offsets. At most
    :data:`FAIR_NOMINAL_ITERATIONS` iterations.

    Raises:
        EstimationError: the fit did not converge.
    """
    used = obs.used
    start = place_nominal(nominal, obs.q[used], obs.tool_poses()[used],
                          any_mount=obs.eye_to_hand)  # fmt: skip
    fit = refine_on_board(obs, start, placement_indices(nominal.n), stds=stds,
                          max_iter=FAIR_NOMINAL_ITERATIONS,
                          what="the fair nominal (the nominal chain placed on the camera "
                          "stage's poses, board pose, hand-eye and cameras fitted, the chain "
                          "held)")  # fmt: skip
    return replace(fit, model=standard_gauge(fit.model, start.joint_offsets))
