"""The result type of the one-step refinement (:func:`selfcal.calibration.field.joint_refine.joint_refine`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from selfcal.camera import CameraSet, Pinhole, PinholeValues
from selfcal.estimation.gauge import GaugeChoice
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["JointRefinementResult"]


@dataclass
class JointRefinementResult(PinholeValues):
    """Outcome of :func:`joint_refine`. SI units; world = left camera of ``ref_config``.

    Attributes:
        model: refined MCPC model (tool = left camera), world = the refined reference camera.
        model_gauge: the same chain in the optimisation gauge (held parameters at their
            two-stage values).
        camera: the refined camera, shared by every camera of the rig (``fx``, ``mu``, ``cx``,
            ``cy`` its values, px); ``fx_std``, ``mu_std`` (NaN when held) and ``camera_std``
            (every free parameter by name) from the final Jacobian; with ``cameras`` (each
            camera of the rig its own model) they are the first camera's, and
            ``cameras_std`` holds every camera's by camera name.
        T_first_cam: (N, 4, 4) the rig: each camera's pose in the first camera frame (m);
            ``T_left_right`` the second's.
        T_world_cam: (m, N, 4, 4) camera poses of all configurations (NaN if not active).
        point_ids, X_world: reconstructed corners (P, 3) m (NaN: not in the adjustment).
        names: the minimal parameter names (eq. 10 order); ``values`` in ``model``;
            ``std``: standard deviations in the reference-camera frame (like the two-stage
            report; nan for parameters held by the identifiability analysis);
        covariance: (P, P) covariance of all minimal parameters in the reference-camera frame.
        free: mask of the parameters estimated in the optimisation gauge; ``gauge``: the held
            world-frame set; ``held_reason``: name -> why held.
        rms_px: reprojection RMS (2-D norm) over the inliers; ``sigma_px``: a-posteriori noise
            per coordinate; ``n_inliers``, ``n_outliers``.
        iterations: LM iterations summed over rounds; ``rounds``; ``converged``; ``seconds``.
        rank_min_singular: smallest relative singular value of the column-scaled Jacobian at
            the start (gauge check), ``rank``/``n_unknowns`` (NaN and -1: not checked).
    """

    model: MCPCModel
    model_gauge: MCPCModel
    camera: Pinhole
    fx_std: float
    mu_std: float
    T_first_cam: np.ndarray
    T_world_cam: np.ndarray
    ref_config: int
    point_ids: np.ndarray
    X_world: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    free: np.ndarray
    gauge: GaugeChoice
    held_reason: dict[str, str]
    rms_px: float
    sigma_px: float
    n_inliers: int
    n_outliers: int
    iterations: int
    rounds: int
    converged: bool
    seconds: float
    rank_min_singular: float
    rank: int
    n_unknowns: int
    diagnostics: dict = field(default_factory=dict)
    camera_std: dict[str, float] = field(default_factory=dict)
    """Standard deviation of every free camera parameter by name (px or unitless)."""
    cameras: CameraSet | None = None
    """Each camera's refined model (None: ``camera`` is shared by the rig)."""
    cameras_std: dict[str, dict[str, float]] | None = None
    """With ``cameras``: each camera's ``camera_std`` by camera name."""
    inlier: np.ndarray | None = None
    """(k,) bool: the observation rows the final pass fitted (the settled inliers)."""
    sections: tuple = ()
    """The ``calibration.json`` section of every measurement term estimated with the images
    (:mod:`selfcal.terms`), in order."""
    damping: float = 1e-4
    """The damping the final pass's solve ended with (``SolverResult.damping``): a warm start
    for a nearby problem (the fair nominal's fit starts at this estimate's camera and points)."""

    @property
    def T_left_right(self) -> np.ndarray:
        """Pose (4, 4) of the second (right) camera in the first (left) camera frame (m)."""
        if len(self.T_first_cam) < 2:
            return np.full((4, 4), np.nan)
        return self.T_first_cam[1]
