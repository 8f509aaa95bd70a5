"""The per-view misfit of a board calibration as a jitter of the chain's tool pose (issue #29).

A calibration whose model misfits leaves residuals in its own frames (its first camera's pixels
predicted from the joints alone by the stored model) that do not look like corner noise: on
the real Nachi sets (tests/real) 94 % of their energy lies in the span of each frame's 6 pose
columns (``A``, the pixels' derivative by a body twist of the chain's tool: the camera,
eye-to-hand the board), where white corner noise would put 6 of every ``2k`` (3 %), and the
rest is 0.10 px RMS against the 0.43 px corner noise the bounds take from the fit's RMS
(photoneo, ``selfcal calibrate`` on groups 1-5 as the real tier runs it: the block's
``pose_share`` and ``rest_rms_px``; docs/real-data.md). Such a
misfit moves each new view as a small pose error of its own: the drift check
(:mod:`selfcal.calibration.drift.views`) must carry it per view, in that form, or every
directed test of a change rejects an unchanged arm.

Per frame ``i``: ``xi_i = argmin |r_i - A_i xi|`` (m, rad) and
``N_i = s^2 (A_i^T A_i)^-1 + tw_i S_j tw_i^T`` what the corner noise ``s`` (the bounds') and the
joint read-back noise (``S_j``, ``tw_i`` the joints' body twists) give it. The jitter is
counted when ``sum_i xi_i^T N_i^-1 xi_i`` exceeds its ``6 m`` by more than
:data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` standard errors (``sqrt(12 m)``): its
covariance (6, 6) is then the mean of ``xi_i xi_i^T - N_i`` (negative eigenvalues set to 0),
else 0. A calibration that fits (the simulated ones) has none: the fit absorbs part of each
frame's pose span, so its statistic lies below ``6 m``.

The corner noise beside it stays the bounds' (from the fit's RMS, which holds the misfit's
energy too: the prediction counts it twice and is pessimistic). The rest alone (0.10 px on
photoneo) is no corner noise for new views: with it, the check's test of a camera change
rejects the unchanged arm's held-out group (p = 1e-4) and its own frames (5.7e-10); its RMS is
kept beside the jitter (``rest_rms_px``; the two p-values from a script outside the
repository). Nothing here reads truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.misfit import board_view
from selfcal.camera import CameraModel
from selfcal.errors import InputError
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["KEY", "ViewJitter", "view_jitter", "view_jitter_from_json"]

KEY = "view_jitter"
"""The ``accuracy`` block's key of :meth:`ViewJitter.to_json`."""


@dataclass(frozen=True)
class ViewJitter:
    """The per-view pose misfit of a calibration's own frames (module docstring).

    Attributes:
        covariance: (6, 6) of a body twist ``[v; w]`` (m, rad) of the chain's tool per view
            (zeros when not counted); statistic: ``sum xi^T N^-1 xi`` over ``views`` frames
            (expected ``6 views`` without a misfit); counted: it exceeded that (module
            docstring); pose_share: the share of the residuals' sum of squares in the frames'
            pose spans; rest_rms_px: the RMS of the rest (px, per coordinate over its degrees
            of freedom).
    """

    covariance: np.ndarray
    statistic: float
    views: int
    counted: bool
    pose_share: float
    rest_rms_px: float

    def to_json(self) -> dict:
        """The block (SI; px)."""
        return {
            "covariance_si": self.covariance.tolist(),
            "statistic": self.statistic,
            "views": self.views,
            "counted": self.counted,
            "pose_share": self.pose_share,
            "rest_rms_px": self.rest_rms_px,
            "what": "per-view jitter of the chain's tool pose (body twist, m and rad) that the "
            "calibration's own frames show beyond the corner noise; the drift check adds it to "
            "every new view",
        }


def view_jitter(model: MCPCModel, camera: CameraModel, q: np.ndarray,
                frames: list[tuple[int, np.ndarray, np.ndarray]], *, eye_to_hand: bool,
                pixel_sigma_px: float,
                joint_sigma: float | np.ndarray | None) -> ViewJitter | None:  # fmt: skip
    """The per-view misfit (module docstring) of the calibrated ``model`` with its first
    ``camera`` in its own ``frames``: each a frame index into the joints ``q`` (m, n) rad / m,
    its board points (k, 3) m (board frame) and detected pixels (k, 2); ``pixel_sigma_px`` the
    corner noise (the bounds'); ``joint_sigma`` the read-back noise (rad / m, scalar or (n,)) or None (exact).
    None with fewer than 2 frames of 4 corners or more: nothing to estimate it from (the one
    place of that rule).
    """
    frames = [fr for fr in frames if len(fr[1]) >= 4]
    if len(frames) < 2:
        return None
    q_frames = np.asarray(q, float)[[f for f, _, _ in frames]]
    T, tw = fk_tool(model, q_frames), joint_twists(model, q_frames)
    xis, infos, rest, dof, total = [], [], 0.0, 0, 0.0
    for (_, X, uv), Ti in zip(frames, T, strict=True):
        _, uv_hat, A, _ = board_view(camera, Ti, X, eye_to_hand)
        r = (np.asarray(uv, float) - uv_hat).reshape(-1)
        xi, *_ = np.linalg.lstsq(A, r, rcond=None)
        e = r - A @ xi
        rest += float(e @ e)
        total += float(r @ r)
        dof += len(r) - 6
        xis.append(xi)
        infos.append(A.T @ A)
    s2 = pixel_sigma_px**2
    n = len(frames)
    js2 = 0.0 if joint_sigma is None else np.broadcast_to(np.asarray(joint_sigma, float) ** 2,
                                                          (tw.shape[2],))  # fmt: skip
    N = [s2 * np.linalg.inv(info) + (tw[i] * js2) @ tw[i].T for i, info in enumerate(infos)]
    stat = float(sum(x @ np.linalg.solve(Ni, x) for x, Ni in zip(xis, N, strict=True)))
    share = 1.0 - rest / total if total > 0 else 0.0
    rest_rms = float(np.sqrt(rest / dof))
    if stat <= 6 * n + Z_MODEL_ERROR * np.sqrt(12 * n):
        return ViewJitter(np.zeros((6, 6)), stat, n, False, share, rest_rms)
    J = np.mean([np.outer(x, x) - Ni for x, Ni in zip(xis, N, strict=True)], axis=0)
    w, U = np.linalg.eigh((J + J.T) / 2)
    return ViewJitter((U * np.clip(w, 0.0, None)) @ U.T, stat, n, True, share, rest_rms)


def view_jitter_from_json(block: dict | None, where: str) -> ViewJitter | None:
    """The ``accuracy`` block's :data:`KEY` entry, None when absent (a file written before it).

    Raises:
        InputError: the entry is malformed (named, with the fix).
    """
    doc = (block or {}).get(KEY)
    if doc is None:
        return None
    try:
        C = np.asarray(doc["covariance_si"], float)
        out = ViewJitter(C, float(doc["statistic"]), int(doc["views"]), bool(doc["counted"]),
                         float(doc["pose_share"]), float(doc["rest_rms_px"]))  # fmt: skip
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{where}: accuracy.{KEY} is malformed ({exc})",
                         fix="re-run `selfcal calibrate` to write it again") from exc  # fmt: skip
    if C.shape != (6, 6) or not np.all(np.isfinite(C)):
        raise InputError(f"{where}: accuracy.{KEY}.covariance_si must be a finite 6 x 6 matrix",
                         fix="re-run `selfcal calibrate` to write it again")  # fmt: skip
    return out
