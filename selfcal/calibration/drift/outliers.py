"""Corners of new views the drift check leaves out (issue #29): those the calibration's own
outlier rule would drop (:func:`selfcal.calibration.board.calibrate.calibrate_board`: beyond
``max(OUTLIER_PX, OUTLIER_SIGMAS * robust sigma)`` after the fit of each view's pose and the
camera), with the same constants, applied after the same robust fit, the calibration's loss and
scale (:func:`view_outliers` says why).

A real image with one corner detected 5.3 px off (after the views' own fit; the real mecheye
set's group 2, tests/real/test_real_left_out_check.py) otherwise counted as noisy (its own white noise, :func:`selfcal.calibration.drift.views.view_white_px`)
and cost the check its power there, or read as a change; the verdict names every corner left
out (:func:`outlier_line`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from selfcal.calibration.board.calibrate import (
    MAX_OUTLIER_SHARE,
    ROBUST_LOSS,
    ROBUST_SCALE_PX,
    outlier_limit_px,
)
from selfcal.calibration.board.misfit import board_view
from selfcal.calibration.drift.views import MIN_WHITE_DOF, span_basis
from selfcal.camera import CameraModel
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.solver import Evaluation, JacobianPiece, Loss, ParameterBlock, Problem, solve

__all__ = ["Outlier", "drop_outliers", "outlier_line", "view_outliers"]

Outlier = tuple[str, float, float, float]
"""A corner left out: its image's name, its detected pixel ``u, v`` and its 2-D residual after
the views' own fit (px)."""
SHOWN = 5
"""The most corners a verdict's line names (its JSON names all)."""


class _Corners:
    """The corners' 2-D residuals ``Q y - r`` (k, 2) px after a change ``y`` in the orthonormal
    columns ``Q`` (2k, m) of every view's pose and the camera, with the board calibration's
    robust loss (:data:`selfcal.calibration.board.calibrate.ROBUST_LOSS`, its scale): a residual
    block of the one solver."""

    name, dim = "corners", 2

    def __init__(self, Q: np.ndarray, r: np.ndarray) -> None:
        self.Q, self.r = Q, r
        self.loss = Loss(ROBUST_LOSS, ROBUST_SCALE_PX)
        self.cols = np.broadcast_to(np.arange(Q.shape[1]), (len(r) // 2, Q.shape[1]))

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """The residuals (k, 2) px and their derivative by the change (k, 2, m)."""
        e = (self.Q @ values["change"] - self.r).reshape(-1, 2)
        if not jacobian:
            return Evaluation(e)
        J = self.Q.reshape(len(e), 2, -1)
        return Evaluation(e, (JacobianPiece("change", J, self.cols),))


def _robust_errors(M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(k,) every corner's 2-D error (px) after the fit of the residuals ``r`` (2k,) px by the
    columns ``M`` (2k, c) with the board calibration's robust loss and scale, as its first pass
    fits each view's pose and the camera (:func:`selfcal.calibration.board.calibrate.
    calibrate_board`): a plain least-squares fit is pulled by a cluster of outliers (a
    misdetected marker's corners, all off one way) until none of them is beyond the rule."""
    Q = span_basis(M)
    block = _Corners(Q, r)
    res = solve(Problem([ParameterBlock("change", Q.T @ r)], [block]))
    return np.linalg.norm(res.residuals["corners"], axis=1)


def view_outliers(rs: list[np.ndarray], As: list[np.ndarray],
                  Jcs: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:  # fmt: skip
    """The corners of each view the calibration's outlier rule drops: per view ``(out, e)``,
    ``out`` (k,) bool and ``e`` (k,) px every corner's 2-D residual after the least-squares fit
    on the corners kept. As the calibration (its robust pass, then the plain one on the
    inliers): all the views' residuals ``rs`` (2k,) px are fitted by each view's own pose (its
    columns ``As`` (2k, 6)) and one camera change shared by all (their columns ``Jcs`` (2k, c))
    with the calibration's robust loss and scale (:func:`_robust_errors`); out where the error
    after it is at least ``max(OUTLIER_PX, OUTLIER_SIGMAS * sigma)``, ``sigma`` the robust sigma
    of all the corners' (:func:`selfcal.calibration.board.calibrate.outlier_limit_px`, the
    calibration's rule); then a plain least-squares fit of the corners kept gives ``e``.

    Applied to these residuals, not the raw ones: every change the drift check considers (a
    mount, the world, a joint's offset) moves a view's pixels by a change of its pose, to first
    order in the span of its ``A``, and the camera's in that of ``Jc``, the same in every view,
    so the fit takes the change out and a drift moves no corner into the rule (beyond first
    order too: tests/unit/test_drift_view_noise.py's 5 mm move of the camera, 10 px, drops
    nothing but the corner moved 5 px; on the raw
    residuals a coherent drift of a few px would be dropped, or widen the robust sigma so that
    a real outlier stays). The camera is fitted once for all views, not per view: with a view's
    own 8 lens columns a corner at the board's edge 5 px off kept 3 px. In a view with fewer
    than :data:`selfcal.calibration.drift.views.MIN_WHITE_DOF` degrees of freedom beyond its pose none is dropped (the fit
    absorbs what is there), nor where more than
    :data:`selfcal.calibration.board.calibrate.MAX_OUTLIER_SHARE` of its corners would go (a
    view that misfits so widely is what the test is for)."""
    c = Jcs[0].shape[1]
    M = np.zeros((sum(len(r) for r in rs), c + 6 * len(rs)))
    at = 0
    for i, (A, Jc) in enumerate(zip(As, Jcs, strict=True)):
        M[at : at + len(A), :c] = Jc
        M[at : at + len(A), c + 6 * i : c + 6 * i + 6] = A
        at += len(A)
    r = np.concatenate(rs)
    first = _robust_errors(M, r)
    out = first >= outlier_limit_px(first)
    rows = np.repeat(~out, 2)
    coef = np.linalg.lstsq(M[rows], r[rows], rcond=None)[0]
    e = np.linalg.norm((r - M @ coef).reshape(-1, 2), axis=1)
    found, at = [], 0
    for ri in rs:
        k = len(ri) // 2
        o, ei = out[at : at + k].copy(), e[at : at + k]
        if len(ri) - 6 < MIN_WHITE_DOF or np.mean(o) > MAX_OUTLIER_SHARE:
            o[:] = False
        found.append((o, ei))
        at += k
    return found


def drop_outliers(em: ToolErrorModel, camera: CameraModel, q: np.ndarray,
                  views: list[tuple[int, np.ndarray, np.ndarray]], names: list[str], *,
                  eye_to_hand: bool,
                  ) -> tuple[list[tuple[int, np.ndarray, np.ndarray]],
                             tuple[Outlier, ...]]:  # fmt: skip
    """``views`` of ``camera`` (frame ``f`` into ``q`` (m, n) rad / m, board points ``X`` (k, 3)
    m, detected ``uv`` (k, 2) px; ``names`` their images) without the corners the calibration's
    outlier rule drops at the calibration's error model ``em`` (:func:`view_outliers`), and
    what was dropped (:data:`Outlier` each)."""
    rs, As, Jcs = [], [], []
    for f, X, uv in views:
        T = fk_tool(em.model, q[f][None])[0]
        _, uv_hat, A, Jc = board_view(camera, T, X, eye_to_hand)
        rs.append((np.asarray(uv, float) - uv_hat).reshape(-1))
        As.append(A)
        Jcs.append(Jc.reshape(len(A), -1))
    kept, dropped = [], []
    found = view_outliers(rs, As, Jcs) if views else []
    for (f, X, uv), name, (out, e) in zip(views, names, found, strict=True):
        kept.append((f, X[~out], uv[~out]))
        dropped += [(name, float(uv[i, 0]), float(uv[i, 1]), float(e[i]))
                    for i in np.flatnonzero(out)]  # fmt: skip
    return kept, tuple(dropped)


def outlier_line(outliers: tuple[Outlier, ...]) -> str:
    """What a verdict's line adds for the corners left out (empty for none)."""
    if not outliers:
        return ""
    each = ", ".join(
        f"{n} at ({u:.1f}, {v:.1f}) px {e:.1f} px off" for n, u, v, e in outliers[:SHOWN]
    )
    more = ", ..." if len(outliers) > SHOWN else ""
    return (f"; {len(outliers)} corner(s) beyond the calibration's outlier rule after their "
            f"view's own pose fit left out: {each}{more}")  # fmt: skip
