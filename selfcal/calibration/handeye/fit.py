"""One fit of the pose route on the one solver: the camera, the hand-eye ``X`` and the board
mount ``B`` on corner reprojection through the pose chain
(:class:`selfcal.estimation.pose_chain.PoseChainBlock`), the flange poses exact or each with a
correction and its prior (errors in variables: :mod:`selfcal.calibration.handeye.eiv`).

A robust pass (soft-L1, 1 px), the outliers (beyond ``max(outlier_px, 4.5 sigma)``) dropped, a
plain least-squares pass whose covariance ``sigma^2 (J^T J)^-1`` gives the standard deviations;
with corrections the least-squares pass is repeated with the variance components' weights until
they settle. :func:`choose_pose_noise` decides between the exact poses and the corrections by
cross-validation over the views.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from selfcal.calibration.handeye.eiv import (
    DEFAULT_START,
    EXACT,
    PoseNoise,
    redundancy,
    variance_components,
)
from selfcal.camera import CameraModel
from selfcal.camera.camera_set import std_by_name
from selfcal.errors import EstimationError
from selfcal.estimation.pose_chain import FlangePriorBlock, PoseChainBlock, local_pose
from selfcal.estimation.reprojection import robust_sigma
from selfcal.solver import (
    Loss,
    ParameterBlock,
    Problem,
    SolverOptions,
    cost_and_weights,
    covariance,
    solve,
)
from selfcal.transforms import inv_pose

__all__ = ["CV_MARGIN", "CrossValidation", "HandEyeFit", "PoseChoice", "Predictor",
           "chain_predictor", "choose_pose_noise", "corrected_motions", "cross_validate",
           "fit_pose_chain", "predict_better", "predict_corners"]  # fmt: skip

CV_MARGIN = 0.01
"""The pose route's cross-validated choices (:func:`predict_better`) leave their default model
only for one that predicts the left-out views better by more than this (1 % of the RMS)."""
_VCE_MAX = 10
_VCE_TOL = 0.02
"""The variance components' iterations at most, and the change (of the log of every sigma) below
which they have settled (2 %); a sigma the images no longer resolve is held
(:func:`selfcal.calibration.handeye.eiv.variance_components`)."""


@dataclass(frozen=True)
class HandEyeFit:
    """One fit: ``camera`` (and ``camera_std`` of its free parameters; when held, the held
    camera's own, empty when it was taken as exact), ``X`` / ``B`` (4, 4) m, their standard
    deviations ``X_std`` / ``B_std`` (6,) as the local parameters ``[w (rad), v (m)]``
    (rotation about the base axes of each frame's parent, then translation; a held camera's
    own error included when given), ``rms_px`` over the inliers, ``inlier`` (k,) of the observation rows,
    ``sigma_px`` the fitted noise per coordinate, ``iterations``; ``pose_noise`` the flange
    poses' sigmas the fit weighed them with (exact: taken as reported), ``pose_noise_estimated``
    whether from the residuals, ``corrections`` (n, 6) of the flange poses ``[w (rad), v (m)]``
    (:mod:`selfcal.calibration.handeye.eiv`)."""

    camera: CameraModel
    camera_std: dict[str, float]
    X: np.ndarray
    B: np.ndarray
    X_std: np.ndarray
    B_std: np.ndarray
    rms_px: float
    inlier: np.ndarray
    sigma_px: float
    iterations: int
    pose_noise: PoseNoise = EXACT
    pose_noise_estimated: bool = False
    corrections: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))


def predict_corners(camera: CameraModel, X: np.ndarray, B: np.ndarray, A: np.ndarray,
                    view: np.ndarray, points: np.ndarray) -> np.ndarray:  # fmt: skip
    """Pixels (k, 2) of the board ``points`` (k, 3) m in the views ``view`` (k,) through the
    pose chain ``X^-1 A_i B``; NaN behind the camera."""
    T = inv_pose(X)[None] @ np.asarray(A)[view] @ B
    Xc = np.einsum("kij,kj->ki", T[:, :3, :3], points) + T[:, :3, 3]
    uv = camera.project(Xc)
    return np.where(Xc[:, 2:3] > 0, uv, np.nan)


def _problem(cam0: CameraModel, cam: CameraModel, hold_camera: bool, A: np.ndarray,
             X: np.ndarray, B: np.ndarray, c: np.ndarray | None, setup: str, rows: tuple,
             loss: str, scale: np.ndarray | None) -> Problem:  # fmt: skip
    """The fit's problem: the pose chain's corners (``rows`` = view, points, uv) around ``X``,
    ``B``; with corrections ``c`` (n, 6) their block and prior (rows' ``scale``)."""
    view, points, uv = rows
    eiv = c is not None
    block = PoseChainBlock(cam0, A, X, B, view, points, uv, Loss(loss, 1.0),
                           corrections="corrections" if eiv else None,
                           inverted=setup == "eye-in-hand")  # fmt: skip
    params = [
        ParameterBlock("intrinsics", cam.free_values(), held=np.full(cam.n_free, hold_camera)),
        ParameterBlock("X", np.zeros(6)),
        ParameterBlock("B", np.zeros(6)),
    ]
    if c is None or scale is None:
        return Problem(params, [block])
    n = len(A)
    params.append(ParameterBlock("corrections", c, instance=np.repeat(np.arange(n), 6)))
    return Problem(params, [block, FlangePriorBlock(n, scale)])


def fit_pose_chain(cam0: CameraModel, hold_camera: bool, A: np.ndarray, X0: np.ndarray,
                   B0: np.ndarray, view: np.ndarray, points: np.ndarray, uv: np.ndarray,
                   outlier_px: float, max_iter: int, *, setup: str,
                   pose_noise: PoseNoise | None, start_px: float = 1.0, settle: bool = True,
                   robust: bool = True, tol: float = 1e-12,
                   camera_cov: np.ndarray | None = None, sigmas: bool = True) -> HandEyeFit:  # fmt: skip
    """One fit (module docstring) of the camera ``cam0`` (its free parameters held when
    ``hold_camera``), ``X`` and ``B`` from ``X0``, ``B0`` (4, 4) m, on the corner rows ``view``
    (k,), board ``points`` (k, 3) m and pixels ``uv`` (k, 2) through the motions ``A`` (n, 4, 4)
    of ``setup`` (:func:`selfcal.calibration.handeye.calibrate.chain_motions`); rows beyond
    ``max(outlier_px, 4.5 sigma)`` after the robust pass are dropped. ``pose_noise``: the flange
    poses' sigmas (exact: no corrections) or None: estimated from the residuals (variance
    components from :data:`selfcal.calibration.handeye.eiv.DEFAULT_START`); the image noise (px
    per coordinate) starts at ``start_px`` and is estimated likewise (``settle`` False with
    given sigmas: held at ``start_px``, one least-squares pass); ``robust`` False: no robust
    pass (the rows are the inliers already); ``tol``: the solver's; ``camera_cov``: the held
    camera's own covariance (its free parameters, as the camera stage's
    :attr:`selfcal.calibration.board.calibrate.BoardCalibration.cov`), carried into ``X_std`` and
    ``B_std`` (:func:`_camera_share`) and giving ``camera_std`` (None: the camera taken as
    exact, no ``camera_std``); ``sigmas`` False: no
    covariance (the standard deviations 0: a cross-validation's fits need none).

    Raises:
        EstimationError: a pass did not converge.
    """
    eiv = pose_noise is None or not pose_noise.exact
    noise = DEFAULT_START if pose_noise is None else pose_noise
    s_px = start_px
    active = np.ones(len(view), bool)
    X, B, cam = X0, B0, cam0
    c = np.zeros((len(A), 6)) if eiv else None
    sol = prob = None
    estimates = 0
    for loss in ("soft_l1", "linear") if robust else ("linear",):
        rows = (view[active], points[active], uv[active])
        settling = loss == "linear" and eiv and (pose_noise is None or settle)
        for _ in range(_VCE_MAX if settling else 1):
            scale = noise.scale(s_px) if eiv else None
            prob = _problem(cam0, cam, hold_camera, A, X, B, c, setup, rows, loss, scale)
            sol = solve(prob, SolverOptions(tol=tol, max_iterations=max_iter,
                                            eliminate="corrections" if eiv else None))  # fmt: skip
            if sol.status <= 0:
                raise EstimationError(
                    f"the hand-eye fit on corner reprojection ({loss} loss, camera "
                    f"{'held' if hold_camera else 'free'}) did not converge within {max_iter} "
                    f"iterations from the linear start ({sol.message})",
                    fix="check that every pose row belongs to its image and that --setup is right",
                )
            cam = cam0.with_free_values(sol.values["intrinsics"])
            X, B = local_pose(X, sol.values["X"]), local_pose(B, sol.values["B"])
            if not eiv:
                continue
            c = sol.values["corrections"].reshape(-1, 6)
            if not settling:
                continue
            red = redundancy(prob, sol.x, cost_and_weights(prob, prob.evaluate(sol.x))[1])
            step = variance_components(sol.residuals["pose_chain"], red[0], c, red[1], noise)
            if step is None:
                break
            s_new, n_new = step
            n_new = n_new if pose_noise is None else pose_noise
            estimates += 1
            change = max(abs(np.log(n_new.mm / noise.mm)), abs(np.log(n_new.deg / noise.deg)),
                         abs(np.log(s_new / s_px)))  # fmt: skip
            s_px, noise = s_new, n_new
            if change < _VCE_TOL:
                break
        if loss == "soft_l1":
            Ac = A if c is None else corrected_motions(A, c, setup)
            e = np.linalg.norm(predict_corners(cam, X, B, Ac, view, points) - uv, axis=1)
            e = np.where(np.isfinite(e), e, np.inf)
            active = e < max(outlier_px, 4.5 * robust_sigma(e[np.isfinite(e)]))
    assert sol is not None and prob is not None
    r = sol.residuals["pose_chain"]
    dof = max(sum(v.size for v in sol.residuals.values()) - prob.n, 1)
    sigma2 = float(sum(np.sum(v**2) for v in sol.residuals.values())) / dof
    blocks = ["X", "B"] + ([] if hold_camera else ["intrinsics"])
    n_cov = 12 + (0 if hold_camera else cam.n_free)
    cov = (covariance(prob, sol.x, blocks, sigma2=sigma2, eliminate="corrections" if eiv else None)
           if sigmas else np.zeros((n_cov, n_cov)))  # fmt: skip
    if sigmas and hold_camera and camera_cov is not None and cam.n_free:
        rows = (view[active], points[active], uv[active])
        free = _problem(cam0, cam, False, A, X, B, c, setup, rows, "linear",
                        noise.scale(s_px) if eiv else None)  # fmt: skip
        cov = cov + _camera_share(free, np.asarray(camera_cov, float))
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    cam_std = std_by_name(cam, cov[12:, 12:]) if not hold_camera else (
        std_by_name(cam, np.asarray(camera_cov, float))
        if sigmas and camera_cov is not None and cam.n_free else {})  # fmt: skip
    return HandEyeFit(camera=cam, camera_std=cam_std, X=X, B=B, X_std=std[:6], B_std=std[6:12],
                      rms_px=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))), inlier=active,
                      sigma_px=float(np.sqrt(sigma2)), iterations=sol.iterations,
                      pose_noise=noise if eiv else PoseNoise(0.0, 0.0),
                      pose_noise_estimated=pose_noise is None and estimates > 0,
                      corrections=np.zeros((len(A), 6)) if c is None else c)  # fmt: skip


def _camera_share(problem: Problem, camera_cov: np.ndarray) -> np.ndarray:
    """(12, 12) the share of ``X`` and ``B``'s covariance (local parameters) that a held
    camera's own error brings, ``G camera_cov G^T`` with ``G = N_tt^-1 N_tc`` the first-order
    change of the fit's other unknowns ``t`` (X, B, the corrections) per unit of the camera's
    free parameters ``c`` (``N = J^T J`` of ``problem``, the fit with the camera free, at its
    start: the held fit's solution). The camera stage fitted the camera to the same corners with
    a free board pose per image; their correlation is left out (the two-step estimator's usual
    first-order correction)."""
    J = problem.jacobian(problem.x0).tocsc()
    ic = problem.columns("intrinsics")
    it = np.setdiff1d(np.arange(problem.n), ic)
    Jt, Jc = J[:, it], J[:, ic]
    N = (Jt.T @ Jt).tocsc()
    d = np.sqrt(np.maximum(N.diagonal(), 1e-300))
    D = sp.diags(1.0 / d)
    G = splu((D @ N @ D).tocsc()).solve(D @ (Jt.T @ Jc).toarray()) / d[:, None]
    G = G[np.searchsorted(it, np.concatenate([problem.columns("X"), problem.columns("B")]))]
    return G @ camera_cov @ G.T


def corrected_motions(A: np.ndarray, c: np.ndarray, setup: str) -> np.ndarray:
    """The motions ``A`` (n, 4, 4) of ``setup`` with their flange poses corrected by ``c``
    (n, 6) (:class:`selfcal.estimation.pose_chain.PoseChainBlock`)."""
    inverted = setup == "eye-in-hand"
    F = inv_pose(A) if inverted else np.asarray(A, float)
    Fc = np.stack([local_pose(f, ci) for f, ci in zip(F, c)])
    return inv_pose(Fc) if inverted else Fc


@dataclass(frozen=True)
class PoseChoice:
    """The cross-validation of :func:`choose_pose_noise`: the held-out RMS (px) of the views'
    corners predicted from their reported flange poses by the fits without them, the poses
    exact (``exact_px``) and with corrections (``eiv_px``), over ``folds`` folds; ``eiv``
    whether the corrections are used (they did not predict worse)."""

    exact_px: float
    eiv_px: float
    folds: int
    eiv: bool


def choose_pose_noise(camera: CameraModel, A: np.ndarray, exact: HandEyeFit, eiv: HandEyeFit,
                      view: np.ndarray, points: np.ndarray, uv: np.ndarray, outlier_px: float,
                      max_iter: int, *, setup: str, folds: int = 8) -> PoseChoice:  # fmt: skip
    """Whether the flange pose corrections with ``eiv``'s sigmas predict new views as well as
    the exact poses (both fits of the held ``camera``, the rows ``view``, ``points``, ``uv``
    as :func:`fit_pose_chain`'s): the views split into ``folds`` folds (every ``folds``-th
    view), each fold's corners predicted from its reported poses by both fits on the others
    (each started from the full fit, the sigmas held, on the inliers of ``exact``, to a
    tolerance of 1e-9). The corrections are dropped when they predict worse by more than
    :data:`CV_MARGIN`: the prediction from reported poses hardly sees how close the hand-eye is
    to the truth (the left-out views lie among the others), which the corrections improve when
    the pose noise is real (docs/handeye.md), so a tie keeps them; a model of independent pose
    errors that predicts new poses worse is not what the data support."""
    predictors = {
        name: chain_predictor(camera, A, start, noise, eiv.sigma_px, view, points, uv,
                                     outlier_px, max_iter, setup)
        for name, start, noise in (("exact", exact, EXACT), ("eiv", eiv, eiv.pose_noise))
    }  # fmt: skip
    cv = cross_validate(view, exact.inlier, uv, predictors, folds)
    worse = predict_better(cv.rms["exact"], cv.rms["eiv"])
    return PoseChoice(cv.rms["exact"], cv.rms["eiv"], cv.folds, not worse)


def predict_better(other_px: float, default_px: float) -> bool:
    """The rule of both cross-validated choices of the pose route (the flange poses'
    corrections, :func:`choose_pose_noise`; the camera,
    :func:`selfcal.calibration.handeye.camera_refinement.choose_camera`): whether the model that
    predicted the left-out views with RMS ``other_px`` (px) replaces the default one
    (``default_px``): only when it is better by more than :data:`CV_MARGIN`, ``default_px >
    (1 + CV_MARGIN) other_px``; a smaller difference is within what eight folds of a dozen
    images resolve, and keeps the default."""
    return default_px > (1.0 + CV_MARGIN) * other_px


Predictor = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""A model fitted on the ``train`` rows (bool mask) predicting the pixels (t, 2) of the ``test``
rows (bool mask); raises :class:`selfcal.errors.EstimationError` when its fit fails."""


@dataclass(frozen=True)
class CrossValidation:
    """:func:`cross_validate`'s result: per predictor the held-out ``rms`` (px) over every
    left-out corner and ``fold_rms`` (folds,) px over each fold's; the number of ``folds`` and
    of left-out corners in each (``fold_count``)."""

    rms: dict[str, float]
    fold_rms: dict[str, tuple[float, ...]]
    folds: int
    fold_count: tuple[int, ...] = ()


def cross_validate(view: np.ndarray, inlier: np.ndarray, uv: np.ndarray,
                   predictors: Mapping[str, Predictor], folds: int = 8) -> CrossValidation:  # fmt: skip
    """The held-out RMS (px) of each of ``predictors`` over ``folds`` folds of the views
    (every ``folds``-th view of ``view`` (k,) out), each fold's ``inlier`` rows predicted by the
    fits on the other views' inliers (a failed fit or a corner behind the camera: infinite)."""
    views = np.unique(view)
    k = int(min(folds, len(views)))
    sq = {m: np.zeros(k) for m in predictors}
    count = np.zeros(k)
    for f in range(k):
        out = np.isin(view, views[f::k])
        test, train = out & inlier, ~out & inlier
        count[f] = int(test.sum())
        for name, predict in predictors.items():
            try:
                e2 = float(np.sum((predict(train, test) - uv[test]) ** 2))
            except EstimationError:
                e2 = float("inf")
            sq[name][f] = e2 if np.isfinite(e2) else float("inf")
    n = np.maximum(count, 1)
    return CrossValidation(
        rms={m: float(np.sqrt(v.sum() / max(count.sum(), 1))) for m, v in sq.items()},
        fold_rms={m: tuple(np.sqrt(v / n).tolist()) for m, v in sq.items()}, folds=k,
        fold_count=tuple(int(c) for c in count))  # fmt: skip


def chain_predictor(camera: CameraModel | Callable[[np.ndarray], CameraModel], A: np.ndarray,
                           start: HandEyeFit, noise: PoseNoise, start_px: float, view: np.ndarray,
                           points: np.ndarray, uv: np.ndarray, outlier_px: float, max_iter: int,
                           setup: str, hold_camera: bool = True) -> Predictor:  # fmt: skip
    """The :data:`Predictor` of the fit of ``camera`` (held, or free with ``hold_camera``
    False), ``X`` and ``B`` from ``start``'s, the flange poses weighed by ``noise`` (held), on
    the training rows without a robust pass, to a tolerance of 1e-9, without sigmas.
    ``camera`` may be a function of the training rows (bool mask) giving each fold's camera."""

    def predict(train: np.ndarray, test: np.ndarray) -> np.ndarray:
        cam = camera(train) if callable(camera) else camera
        g = fit_pose_chain(cam, hold_camera, A, start.X, start.B, view[train], points[train],
                           uv[train], outlier_px, max_iter, setup=setup, pose_noise=noise,
                           start_px=start_px, settle=False, robust=False, tol=1e-9,
                           sigmas=False)  # fmt: skip
        return predict_corners(g.camera, g.X, g.B, A, view[test], points[test])

    return predict
