"""The fair nominal of a tracker calibration: the nominal chain with the tracker frame and the tool
fitted by the same objective.

A kinematic calibration is judged against what the nominal robot does once everything but its
kinematics is estimated from the same data: the tracker frame (tracker <- robot base, 6
degrees of freedom), the tool point on the flange (positions, distances) or the measured tool
frame on the flange (poses, 6 degrees of freedom). Those are the unknowns here; the chain between
them stays the robot file's. The residual blocks, their weights and the solver are those of
:func:`selfcal.calibration.tracker.identify.identify_tracker` (:func:`selfcal.estimation.tracker.tracker_terms`
with no kinematic coordinate free), so the two fit errors compare like for like.

Units: SI inside; fields ending in ``_mm`` / ``_deg`` are for reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.tracker.identify import no_convergence
from selfcal.estimation.tracker import TrackerMeasurements, tracker_terms
from selfcal.kinematics.forward import fk_tool, pose_error
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.solver import ParameterBlock, Problem, SolverOptions, solve
from selfcal.transforms import make_pose

__all__ = ["NominalFit", "fit_nominal", "pose_errors"]


@dataclass(frozen=True)
class NominalFit:
    """The nominal chain placed and tooled by :func:`fit_nominal`.

    Attributes:
        model: the nominal chain whose tool is the fitted tool point (positions) or the fitted
            measured tool frame (poses) on the nominal flange (rad, m).
        T_meas_fit: (4, 4) tracker frame <- the nominal base frame (m); the identity for
            distances alone (they do not see the tracker frame).
        rms_mm, rms_deg, rms_distance_mm: the fit's RMS position error (mm), rotation error
            (deg, poses) and distance error (mm); nan where there is no such row.
        converged: whether the solver converged.
    """

    model: MCPCModel
    T_meas_fit: np.ndarray
    rms_mm: float
    rms_deg: float
    rms_distance_mm: float
    converged: bool

    def predict_poses(self, q: np.ndarray) -> np.ndarray:
        """Tool poses ``T_tracker_tool`` (m, 4, 4) at joints ``q`` (m, n) rad / m."""
        return self.T_meas_fit @ fk_tool(self.model, np.atleast_2d(q))


def pose_errors(T_pred: np.ndarray, xyz: np.ndarray, R: np.ndarray | None) -> tuple:
    """``(position error (m,) mm, rotation error (m,) deg or None)`` of predicted tool poses
    ``T_pred`` (m, 4, 4) against measured positions ``xyz`` (m, 3) m and orientations ``R``
    (m, 3, 3) or None; the rotation error is the angle of ``R_pred^T R``."""
    pos = np.linalg.norm(T_pred[:, :3, 3] - xyz, axis=1) * 1e3
    if R is None:
        return pos, None
    return pos, np.degrees(np.linalg.norm(pose_error(T_pred, make_pose(R, xyz))[:, 3:], axis=1))


def fit_nominal(
    model: MCPCModel,
    meas: TrackerMeasurements,
    *,
    sigma_t_m: float = 1e-4,
    sigma_r_rad: float = 1e-4,
    max_iterations: int = 100,
    tol: float = 1e-8,
) -> NominalFit:
    """Fit the tracker frame and the tool of the nominal chain ``model`` (tool = flange) to
    ``meas`` (:class:`TrackerMeasurements`, SI, tracker frame); the chain itself is held.

    ``sigma_t_m`` weighs positions and distances, ``sigma_r_rad`` the rotations of poses, as in
    :func:`selfcal.calibration.tracker.identify.identify_tracker` (the same residual blocks).

    Raises:
        EstimationError: the solver did not converge (the message says what was tried).
    """
    # the chain's block holds one coordinate, held: the blocks' kinematic Jacobian piece then has
    # a column, which the solver drops (it takes no piece without columns)
    first = np.zeros(1, np.int64)
    blocks, params = tracker_terms(meas, model, first, "mcpc", sigma_t_m, sigma_r_rad)
    held = ParameterBlock("mcpc", model.params.reshape(-1)[first], held=np.ones(1, bool))
    prob = Problem([held, *params], blocks)
    sol = solve(prob, SolverOptions(tol=tol, max_iterations=max_iterations))
    if not sol.converged:
        tried = ("the fair nominal (the nominal chain with the tracker frame and the tool fitted) "
                 f"did not converge in {max_iterations} Levenberg-Marquardt iterations "
                 f"({sol.message})")  # fmt: skip
        raise no_convergence(prob, blocks, tried, "please report it with the data")
    lay = blocks[0].layout
    T_frame = lay.tracker_frame(sol.values)
    if lay.tool is not None:  # poses: the measured tool frame
        tool = lay.tool_frame(sol.values)
    else:  # positions and/or distances: the tool point
        tool = make_pose(np.eye(3), lay.tool_point(sol.values))
    rms = {"pos": np.nan, "rot": np.nan, "dist": np.nan}
    for b in blocks:
        r = sol.residuals[b.name] / np.reshape(b.w, (len(b.w), -1))
        if b.name == "tracker_distances":
            rms["dist"] = float(np.sqrt(np.mean(r**2))) * 1e3
            continue
        rms["pos"] = float(np.sqrt(np.mean(np.sum(r[:, :3] ** 2, axis=1)))) * 1e3
        if r.shape[1] == 6:
            rms["rot"] = float(np.degrees(np.sqrt(np.mean(np.sum(r[:, 3:] ** 2, axis=1)))))
    return NominalFit(
        model=model.with_tool(tool),
        T_meas_fit=T_frame,
        rms_mm=rms["pos"],
        rms_deg=rms["rot"],
        rms_distance_mm=rms["dist"],
        converged=bool(sol.converged),
    )
