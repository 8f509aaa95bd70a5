"""What one posture of a field plan tells the field route about the tool point (``selfcal plan
--target FIELD.toml``, issue #30; :mod:`selfcal.calibration.field.plan`): each candidate's Fisher
information about the camera's free parameters and the free kinematic parameters, and the
weight that turns their covariance into the predicted tool-point error over the workspace, so
that the field plan chooses with the board plan's criterion and code
(:mod:`selfcal.calibration.board.plan.greedy`: ``sqrt(trace(G C))``, ``C`` the kinematic block
of the inverse information).

The information is the field route's own (the joint refinement's whitened Jacobian,
:func:`selfcal.calibration.field.bounds.fisher_jacobian`, of every candidate at once) with each
posture's joint read-back errors eliminated under their prior (the Schur complement of the
posture's own corrections, as :func:`selfcal.calibration.board.plan.information.frame_information`
does for a board) and the markers' corners taken as known: with the corners unknown every
posture's information shares them (some 240 unknowns for 20 markers), and the board plan's
greedy choice over that many unknowns took minutes for 400 candidates where the known corners
take seconds (a trial, session 19). The plan's forecast keeps the corners unknown
(:func:`selfcal.calibration.field.plan.field_forecast`), and the plan is judged by it.
SI units, px.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import sparse

from selfcal.calibration.field.bounds import FisherSetup, fisher_jacobian
from selfcal.calibration.field.bounds_setup import predicted_setup
from selfcal.calibration.field.joint_refine import choose_gauge
from selfcal.calibration.field.plan_sight import Supports
from selfcal.camera import Rig
from selfcal.estimation.epipolar import MIN_SHARED
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.estimation.observations import ViewLayout
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.transforms import inv_pose

__all__ = [
    "FieldLayout",
    "PostureRows",
    "free_kinematics",
    "frame_information",
    "posture_rows",
    "rows_information",
    "tool_weight",
]


@dataclass(frozen=True)
class FieldLayout:
    """The markers a forecast assumes: ``ids`` (K,), their corners ``corners_world`` (K, 4, 3) m
    and normals (K, 3) in the base frame, the two ``scale_ids`` whose centres lie the known
    ``scale_length_m`` (m) apart; ``supports`` the raised supports that can hide a marker from
    a planned posture (:class:`selfcal.calibration.field.plan_sight.Supports`; None: none
    known, no line of sight checked)."""

    ids: np.ndarray
    corners_world: np.ndarray
    normals_world: np.ndarray
    scale_ids: tuple[int, int]
    scale_length_m: float
    supports: Supports | None = None


def free_kinematics(model_cam: MCPCModel) -> np.ndarray:
    """(k,) bool over the minimal parameters of ``model_cam``: those the field route estimates
    (every one but the world gauge's six, :func:`selfcal.calibration.field.joint_refine.
    choose_gauge`), in the order of the forecast's and the information's kinematic block."""
    held = set(choose_gauge(model_cam).held)
    return np.array([nm not in held for nm in param_names(minimal_indices(model_cam.joint_types))])


def tool_weight(
    model_cam: MCPCModel, workspace: np.ndarray, T_flange_cam: np.ndarray
) -> np.ndarray:
    """(k, k) the aligned tool weight ``G`` of the free kinematic parameters
    (:func:`free_kinematics`): ``trace(G C)`` is the squared RMS error of the flange centre
    (``inv(T_flange_cam)`` from the camera) over the ``workspace`` postures (w, n) rad after the
    best rigid alignment (:func:`selfcal.estimation.joint_report.aligned_tool_weight`; the
    gauge's parameters held, so their rows and columns drop out). m^2 per unit^2."""
    free = free_kinematics(model_cam)
    G = aligned_tool_weight(model_cam, workspace, inv_pose(np.asarray(T_flange_cam, dtype=float)))
    return G[np.ix_(free, free)]


def frame_information(
    model_cam: MCPCModel,
    rig: Rig,
    q: np.ndarray,
    layout: FieldLayout,
    *,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None,
) -> np.ndarray:
    """(m, p, p) the Fisher information of each posture ``q`` (m, n) rad about ``[the camera's
    free parameters, the free kinematic parameters]`` (:func:`free_kinematics`; px, rad, m) of
    the field route (module docstring): the markers of ``layout`` seen by ``rig`` at the nominal
    chain ``model_cam`` (tool = the first camera) as the analytic simulator decides it, corner
    noise ``pixel_sigma_px`` px, the read-back noise ``joint_sigma`` (n,) rad eliminated per
    posture (None: exact joints). A posture that sees no marker adds nothing (zeros), nor does
    one whose first camera sees fewer than :data:`selfcal.estimation.epipolar.MIN_SHARED`
    corners: the route's first pass cannot register its view (no pair shares enough points),
    so a recording drops it (a plan's posture that saw 2 of 20 markers was dropped so).

    Raises:
        BoundsError: a scale marker is not seen twice among the postures.
    """
    fs = predicted_setup(model_cam, q, rig, layout.ids, layout.corners_world,
                         layout.normals_world, layout.scale_ids, layout.scale_length_m,
                         pixel_sigma_px=pixel_sigma_px, joint_sigma=joint_sigma)  # fmt: skip
    return rows_information(posture_rows(fs, rig.n_cameras))


def rows_information(pr: PostureRows) -> np.ndarray:
    """(m, p, p) :func:`frame_information` of the candidates of ``pr``
    (:func:`posture_rows`), for a caller that also needs the rows (the corners-unknown
    criterion, :func:`selfcal.calibration.field.plan_corners.corner_blocks`)."""
    m = len(pr.registered)
    cols = pr.lay.kin_cols
    F = np.zeros((m, len(cols), len(cols)))
    for i in map(int, np.flatnonzero(pr.registered)):  # unregistered: no information
        Ri = pr.R[pr.rows(i)]
        A = Ri[:, cols].toarray()
        F[i] = A.T @ A
        if pr.prior is not None and len(A):  # eliminate the posture's read-back errors
            B = Ri[:, pr.dq_cols(i)].toarray()
            BA = B.T @ A
            F[i] -= BA.T @ np.linalg.solve(B.T @ B + pr.prior, BA)
    return F


@dataclass(frozen=True)
class PostureRows:
    """The field route's whitened Jacobian of candidate postures (``J``, ``lay``:
    :func:`selfcal.calibration.field.bounds.fisher_jacobian` of the setup ``fs``) with its
    reprojection rows sorted by posture: ``R`` (csr) those rows, ``point`` (rows,) each row's
    point index, ``ends`` (m,) where each posture's rows end; ``registered`` (m,) the postures
    whose first camera sees :data:`selfcal.estimation.epipolar.MIN_SHARED` corners or more;
    ``prior`` (n, n) the read-back errors' information (None: exact joints)."""

    fs: FisherSetup
    J: sparse.csr_matrix
    lay: Any
    R: sparse.csr_matrix
    point: np.ndarray
    ends: np.ndarray
    registered: np.ndarray
    prior: np.ndarray | None

    def rows(self, i: int) -> slice:
        """Posture ``i``'s rows of ``R``."""
        return slice(int(self.ends[i - 1]) if i else 0, int(self.ends[i]))

    def dq_cols(self, i: int) -> np.ndarray:
        """Posture ``i``'s read-back errors' columns of ``J``."""
        n = self.fs.model.n
        return self.lay.n_camera + np.asarray(self.lay.pose_model.dq_cols[n * i : n * (i + 1)])


def posture_rows(fs: FisherSetup, n_cameras: int) -> PostureRows:
    """The :class:`PostureRows` of the setup ``fs`` (its ``n_cameras`` cameras' views of the
    markers at the postures, e.g. :func:`selfcal.calibration.field.bounds_setup.predicted_setup`:
    as the analytic simulator decides it; its read-back noise ``joint_sigma``, None: exact)."""
    m, n = np.atleast_2d(fs.q).shape
    joint_sigma = fs.joint_sigma
    J, lay = fisher_jacobian(fs)  # whitened: J^T J is the information
    views = ViewLayout(m, n_cameras)
    frame = views.frame(np.asarray(fs.view))
    rows = np.repeat(frame, 2)  # the reprojection block's rows, u and v of each corner, first
    order = np.argsort(rows, kind="stable")
    first = np.bincount(frame[views.camera(np.asarray(fs.view)) == 0], minlength=m)
    prior = None if joint_sigma is None else np.diag(1.0 / np.broadcast_to(joint_sigma, (n,)) ** 2)
    return PostureRows(fs, J.tocsr(), lay, J[: len(rows)][order].tocsr(),
                       np.repeat(np.asarray(fs.pidx), 2)[order],
                       np.cumsum(np.bincount(rows, minlength=m)), first >= MIN_SHARED, prior)  # fmt: skip
