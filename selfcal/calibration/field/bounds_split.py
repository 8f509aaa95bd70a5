"""The field route's tool-point error for marker corners whose errors are not white: each
marker's centre and its shape err with noise levels of their own (issue #30).

A rendered marker's four detected corners err together less than independent noise of their
RMS makes them: most of their error moves the corners against each other (the marker's shape),
and its centre errs less (docs/plan.md, "What the rendered draws gain over the forecast";
:mod:`selfcal.benchmarks.plan.field_corner_parts`). Split each
view of a marker's eight corner coordinates ``e`` into its centre's part ``P_c e`` (every corner
moved by the four corners' mean error) and its shape's ``P_s e = e - P_c e``, with covariances
``centre_sigma^2 P_c`` and ``shape_sigma^2 P_s`` (px; white noise of ``s`` px per coordinate
has both ``s``). The field route's estimate (least squares weighted for white corner noise
of the setup's ``pixel_sigma_px``) then has the covariance
``N^-1 J^T Cov J N^-1`` (``J`` the whitened Jacobian of
:func:`selfcal.calibration.field.bounds.fisher_jacobian`, ``N = J^T J``): the Cramer-Rao
bound's when both levels are ``pixel_sigma_px``. SI units, px.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse

from selfcal.calibration.field.bounds import (
    BoundsError,
    CramerRao,
    FisherSetup,
    _fisher_problem,
    cramer_rao,
)
from selfcal.target import CORNERS_PER_MARKER

__all__ = ["split_covariance", "split_tool_rms"]


def _centre_projector(n_obs: int) -> sparse.csr_matrix:
    """``P_c`` over ``n_obs`` corners' rows (u, v of each corner in turn), four corners a view
    of one marker: each coordinate replaced by its four corners' mean."""
    block = np.kron(np.full((CORNERS_PER_MARKER,) * 2, 1.0 / CORNERS_PER_MARKER), np.eye(2))
    return sparse.block_diag([block] * (n_obs // CORNERS_PER_MARKER), format="csr")


def split_covariance(
    s: FisherSetup, *, centre_sigma_px: float, shape_sigma_px: float
) -> np.ndarray:
    """(k, k) the covariance of the free kinematic parameters (the order of
    :attr:`selfcal.calibration.field.bounds.CramerRao.cov_free`) the field route estimates from
    the setup's corners when each view of a marker errs by ``centre_sigma_px`` at its centre and
    ``shape_sigma_px`` in its shape (module docstring), the read-back errors as the setup models
    them; the setup's ``pixel_sigma_px`` is the route's weighting.

    Raises:
        BoundsError: the setup's observations are not four corners of one marker per view in
            turn (:func:`selfcal.calibration.field.bounds_setup.predicted_setup`'s order), a
            noise level is negative, or the information is singular.
    """
    view = np.asarray(s.view)
    pidx = np.asarray(s.pidx)
    k4 = CORNERS_PER_MARKER
    if (len(view) % k4 or np.any(view.reshape(-1, k4) != view[::k4, None])
            or np.any(pidx.reshape(-1, k4) // k4 != pidx[::k4, None] // k4)):  # fmt: skip
        raise BoundsError("the setup's observations are not a marker's four corners per view in "
                          "turn (predicted_setup's order)")  # fmt: skip
    if min(centre_sigma_px, shape_sigma_px) < 0:
        raise BoundsError(f"noise levels must be >= 0 px, got centre {centre_sigma_px}, shape "
                          f"{shape_sigma_px}")  # fmt: skip
    prob, x, lay = _fisher_problem(s)
    J = (prob.jac(x) / s.pixel_sigma_px).tocsr()
    rows = 2 * len(view)
    Jr, Je = J[:rows], J[rows:]
    Pc = _centre_projector(len(view))
    A_c = (Jr.T @ (Pc @ Jr)).toarray()
    A_r = (Jr.T @ Jr).toarray()
    A_e = (Je.T @ Je).toarray()
    N = A_r + A_e
    cols = lay.kin_cols[lay.n_camera :]
    E = np.zeros((N.shape[0], len(cols)))
    E[cols, np.arange(len(cols))] = 1.0
    try:
        W = np.linalg.solve(N, E)
    except np.linalg.LinAlgError as exc:
        raise BoundsError("the Fisher information is singular for these data") from exc
    c2 = (centre_sigma_px / s.pixel_sigma_px) ** 2
    s2 = (shape_sigma_px / s.pixel_sigma_px) ** 2
    cov = W.T @ (c2 * A_c + s2 * (A_r - A_c) + A_e) @ W
    return 0.5 * (cov + cov.T)


def split_tool_rms(
    s: FisherSetup,
    q: np.ndarray,
    T_cam_point: np.ndarray,
    *,
    centre_sigma_px: float,
    shape_sigma_px: float,
    bound: CramerRao | None = None,
) -> float:
    """The RMS error (m) of a camera-attached point (``T_cam_point``) over postures ``q`` (w, n)
    rad after the best rigid alignment (as :meth:`CramerRao.aligned_tool_rms`) of the field
    route's estimate from the setup's corners with the marker centres' and shapes' noise
    (:func:`split_covariance`); ``bound``: the setup's :func:`cramer_rao` if already made."""
    cr = cramer_rao(s) if bound is None else bound
    cov = split_covariance(s, centre_sigma_px=centre_sigma_px, shape_sigma_px=shape_sigma_px)
    return dataclasses.replace(cr, cov_free=cov).aligned_tool_rms(q, T_cam_point)
