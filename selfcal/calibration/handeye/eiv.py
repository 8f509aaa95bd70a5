"""Errors in variables for the pose route: the reported flange poses as noisy measurements.

A robot's reported flange pose carries an error (its controller's kinematic model, backlash,
the pose sensor's resolution) that moves every corner of its image together. Taken as exact,
that error goes into the hand-eye; here every view's flange pose gets a correction ``[w, v]``
(rotation vector rad about the flange's origin, translation m in the base frame:
:class:`selfcal.estimation.pose_chain.PoseChainBlock` with a ``corrections`` block, one Schur
instance per view) tied to zero by :class:`selfcal.estimation.pose_chain.FlangePriorBlock` with
the pose sensor's noise, jointly with the hand-eye, the board mount and the camera on the one
solver. The objective is the weighted sum ``sum |r_px|^2 / s_px^2 + |w|^2 / s_rot^2 +
|v|^2 / s_mm^2`` (the image rows in px, the priors scaled by ``s_px / s``).

The sigmas: given (:class:`PoseNoise`), or estimated from the residuals by variance components
(Foerstner's iteration): each group ``g`` (image rows, rotation priors, translation priors)
gets ``s_g^2 = e_g^T e_g / r_g`` with ``r_g = n_g - tr(J_g N^-1 J_g^T)`` its redundancy at the
solution, and the fit is solved again with the new weights until the sigmas settle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

from selfcal.errors import UsageError
from selfcal.solver import Problem

__all__ = ["PoseNoise", "EXACT", "DEFAULT_START", "FLOOR", "FLOOR_PX", "RESOLVED", "redundancy",
           "variance_components"]  # fmt: skip


@dataclass(frozen=True)
class PoseNoise:
    """The flange pose sensor's noise per axis: ``mm`` (translation, mm) and ``deg``
    (rotation, degrees); both 0: the poses are taken as exact (no corrections)."""

    mm: float
    deg: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mm) and np.isfinite(self.deg)) or self.mm < 0 or self.deg < 0:
            raise UsageError(f"pose noise {self.mm} mm, {self.deg} deg: give finite sigmas >= 0")
        if (self.mm == 0) != (self.deg == 0):
            raise UsageError(
                f"pose noise {self.mm} mm, {self.deg} deg: both 0 (exact poses) or both > 0"
            )

    @property
    def exact(self) -> bool:
        """Whether the poses are taken as exact."""
        return self.mm == 0

    def scale(self, sigma_px: float) -> np.ndarray:
        """The prior rows' scale (6,): ``sigma_px`` over the sigma of each correction coordinate
        (``[w (rad), v (m)]``)."""
        return np.r_[
            np.full(3, sigma_px / np.radians(self.deg)), np.full(3, sigma_px / (self.mm * 1e-3))
        ]


EXACT = PoseNoise(0.0, 0.0)
"""The flange poses taken as exact (no corrections)."""
DEFAULT_START = PoseNoise(0.2, 0.02)
"""Where the variance components start when the user gives no sigmas (a real arm: 0.1-1 mm,
0.01-0.1 deg)."""
FLOOR = PoseNoise(1e-4, 1e-5)
"""The estimated sigmas stay above this (a pose sensor without noise drives its variance
component to zero; beyond this the corrections are nil to any precision that matters)."""


RESOLVED = 0.05
"""A pose group's variance component is estimated while its redundancy is at least this share
of its rows (:func:`variance_components`)."""
FLOOR_PX = 1e-6
"""The estimated image noise (px) stays above this (noise-free corners)."""


def redundancy(problem: Problem, x: np.ndarray, weights: list[np.ndarray]) -> list[np.ndarray]:
    """Per residual block the redundancy of each of its rows' coordinates (k, d):
    ``diag(J N^-1 J^T)`` subtracted from 1, ``N = J^T W J`` at ``x`` with the IRLS row
    ``weights`` (:func:`selfcal.solver.cost_and_weights`); they sum to rows - unknowns."""
    evals = problem.evaluate(x, jacobian=True)
    J = problem.sparse_jacobian(evals).toarray()
    dims = [ev.residuals.shape for ev in evals]
    sw = np.concatenate([np.repeat(np.sqrt(w), d) for w, (_, d) in zip(weights, dims)])
    Jw = J * sw[:, None]
    N = Jw.T @ Jw
    try:
        L = np.linalg.cholesky(N)
        G = solve_triangular(L, Jw.T, lower=True)  # h_ii = |L^-1 j_i|^2
        h = np.einsum("ij,ij->j", G, G)
    except np.linalg.LinAlgError:  # singular: the minimum-norm inverse
        h = np.einsum("ij,ji->i", Jw, np.linalg.pinv(N, hermitian=True) @ Jw.T)
    out, row = [], 0
    for k, d in dims:
        out.append((1.0 - h[row : row + k * d]).reshape(k, d))
        row += k * d
    return out


def variance_components(
    image: np.ndarray,
    image_r: np.ndarray,
    corrections: np.ndarray,
    prior_r: np.ndarray,
    previous: PoseNoise,
) -> tuple[float, PoseNoise] | None:
    """One variance-component step: the image noise (px per coordinate) and the pose noise of
    the image residuals ``image`` (k, 2) px with their redundancies ``image_r`` (k, 2), and the
    corrections (n, 6) ``[w rad, v m]`` with the prior rows' redundancies ``prior_r`` (n, 6).
    A pose group (rotations, translations) whose redundancy is below :data:`RESOLVED` of its
    rows keeps its ``previous`` sigma: its prior holds the corrections at nearly nothing and
    the images no longer resolve it (a sigma on its way to zero). None when the image rows have
    no redundancy to estimate from (fewer than 0.5)."""
    r_img = float(image_r.sum())
    if r_img < 0.5:
        return None
    s_px = max(np.sqrt(float(np.sum(image**2)) / r_img), FLOOR_PX)
    out = []
    groups = ((slice(3, 6), previous.mm, FLOOR.mm, 1e3),
              (slice(0, 3), previous.deg, FLOOR.deg, np.degrees(1.0)))  # fmt: skip
    for cols, prev, floor, unit in groups:
        r = float(prior_r[:, cols].sum())
        if r < max(0.5, RESOLVED * prior_r[:, cols].size):
            out.append(prev)
        else:
            out.append(max(unit * np.sqrt(float(np.sum(corrections[:, cols] ** 2)) / r), floor))
    return s_px, PoseNoise(float(out[0]), float(out[1]))
