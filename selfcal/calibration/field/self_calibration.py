"""Camera self-calibration of a wrist camera rig from marker-corner correspondences (paper III).

:func:`self_calibrate` is a short sequence of named steps over point correspondences:

1. :func:`selfcal.calibration.field.initialise.initialise` -- from the images alone: fundamental matrices, ``fx``
   and ``mu`` from the Mendonca-Cipolla cost with the principal point known (image centre),
   essential matrices, two-view reconstruction and incremental PnP registration;
2. :func:`selfcal.calibration.field.adjust.gauge` -- world = first (left) camera of the reference
   configuration, scale = the rig's baseline;
3. :func:`selfcal.calibration.field.adjust.adjust` -- sparse bundle adjustment over the camera's free
   parameters (``fx``, ``mu``), the camera poses and the 3-D points with a robust loss,
   gross-outlier rejection, then a final least-squares pass; by default the poses are one
   first-camera pose per configuration plus one shared transform per further camera (rig);
4. checks of the fit (residuals, cheirality, whether the views determine ``fx``);
5. scale from the known distance between two markers (eqs. 20-24) and the sign choice against a
   nominal camera trajectory (:mod:`selfcal.estimation.scale_sign`).

Frames, units and gauge of the result (:class:`SelfCalibrationResult`):

- world frame = the first (left) camera frame of configuration ``ref_config`` (the registered
  configuration with the lowest ``ref_scores``, by default the first registered one):
  ``T_world_cam[ref_config, 0] = I``;
- during the bundle adjustment the scale gauge is the stereo baseline ``|t(T_left_right)| = 1``;
  afterwards everything is multiplied by ``k = d / d_hat`` so that lengths are in metres
  (``is_metric``); without scale markers the units stay "baselines" and ``is_metric`` is False;
- views follow :class:`selfcal.estimation.observations.ViewLayout` (camera 0 = left, 1 = right);
  ``T_world_cam`` has shape (m, N, 4, 4) and is NaN for configurations that could not be
  registered.

Every failure mode raises a subclass of :class:`SelfCalibrationError` whose message names the
problem and what to change; no silently wrong numbers are returned.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.field.adjust import (
    OUTLIER_FLOOR_PX,
    Adjustment,
    Reconstruction,
    adjust,
    gauge,
    residuals,
    rig_from_views,
)
from selfcal.calibration.field.initialise import InitialReconstruction, initialise
from selfcal.camera import CameraSet, LensCamera, Pinhole, PinholeValues, first_camera, with_pinhole
from selfcal.camera.camera_set import free_std, unproject_views
from selfcal.errors import InputError, UsageTypeError
from selfcal.estimation.observations import Observations
from selfcal.estimation.scale_sign import (
    SignChoice,
    check_scale_markers_seen,
    cheirality_fraction,
    scale_from_markers,
    sign_from_nominal,
)
from selfcal.estimation.selfcal_errors import (
    ConvergenceError,
    DegenerateConfigurationError,
    InsufficientDataError,
    ScaleMarkerError,
    SelfCalibrationError,
)
from selfcal.kinematics.trajectory import optical_axes_convergence
from selfcal.transforms import inv_pose

__all__ = [
    "Observations",
    "SelfCalibrationError",
    "InsufficientDataError",
    "DegenerateConfigurationError",
    "ScaleMarkerError",
    "ConvergenceError",
    "SelfCalibrationResult",
    "self_calibrate",
]


# ----------------------------------------------------------------------------------- result
@dataclass
class SelfCalibrationResult(PinholeValues):
    """Self-calibration output (see the module docstring for frames, units and gauge).

    ``T_world_cam`` (m, N, 4, 4): pose of camera c of configuration i in the world frame (the
    first camera of ``ref_config``); NaN where ``registered`` is False. ``T_first_cam`` (N, 4,
    4): the rig, each camera's pose in the first camera frame (``T_left_right`` the second's;
    NaN where not determined). ``X_world`` (P, 3) for ``point_ids`` (feature ids,
    :mod:`selfcal.target`; NaN if not reconstructed). ``residuals`` (k, 2) px per observation row
    (projected - observed; NaN if unmodelled), ``inlier`` (k,) the rows used by the final
    adjustment, ``rms_px = sqrt(mean |r|^2)`` over the inliers (2-D norm: ~ sigma * sqrt(2) for
    Gaussian noise of sigma px per coordinate). ``fx_std``/``mu_std``/``cov_fx_mu`` from the
    final Jacobian with the fitted noise level; ``cov_fx_mu_unit`` for 1 px noise (geometry
    only). ``camera``: the estimated camera, shared by every camera of the rig (``fx``, ``mu``,
    ``cx``, ``cy``, ``width``, ``height`` are its values); with ``cameras`` (a
    :class:`selfcal.camera.CameraSet`: each camera of the rig its own model) ``camera`` is the
    first camera's, and ``cov_fx_mu`` covers every camera's free parameters (``cameras.free``
    order). ``damping``: the damping the final adjustment's solve ended with
    (``SolverResult.damping``), a warm start for the joint refinement that starts from here.
    """

    camera: Pinhole
    T_world_cam: np.ndarray
    registered: np.ndarray
    T_first_cam: np.ndarray
    point_ids: np.ndarray
    X_world: np.ndarray
    residuals: np.ndarray
    inlier: np.ndarray
    rms_px: float
    n_inliers: int
    n_outliers: int
    fx_std: float
    mu_std: float
    cov_fx_mu: np.ndarray
    cov_fx_mu_unit: np.ndarray
    ref_config: int
    is_metric: bool
    scale: float
    d_hat: float
    sign: int
    rig: bool
    fx_init: float
    mu_init: float
    sign_choice: SignChoice | None = None
    diagnostics: dict = field(default_factory=dict)
    cameras: CameraSet | None = None
    damping: float = 1e-4

    @property
    def intrinsics(self) -> Pinhole:
        """:attr:`camera` (the name the callers know)."""
        return self.camera

    @property
    def camera_std(self) -> dict[str, float]:
        """Standard deviation of every free camera parameter by name (``cov_fx_mu`` is the
        covariance of all of them, in ``camera.free`` order; px or unitless)."""
        return free_std(self.cameras or self.camera, self.cov_fx_mu)[0]

    @property
    def cameras_std(self) -> dict[str, dict[str, float]] | None:
        """With :attr:`cameras`: each camera's :attr:`camera_std` by camera name; else None."""
        return None if self.cameras is None else free_std(self.cameras, self.cov_fx_mu)[1]

    @property
    def K(self) -> np.ndarray:
        return self.camera.K

    @property
    def T_left_right(self) -> np.ndarray:
        """Pose (4, 4) of the second (right) camera in the first (left) camera frame (m)."""
        if len(self.T_first_cam) < 2:
            return np.full((4, 4), np.nan)
        return self.T_first_cam[1]

    @property
    def T_cam_world(self) -> np.ndarray:
        """(m, N, 4, 4) inverse poses (world -> camera)."""
        return inv_pose(self.T_world_cam)

    def pixel_sigma_px(self, n_configs: int) -> float:
        """A-posteriori corner noise per coordinate (px): the inlier residuals over the degrees
        of freedom an adjustment of ``n_configs`` configurations leaves (the camera's free
        parameters, a first-camera pose per configuration but the reference, the rig with its
        baseline gauge, the reconstructed points)."""
        inl = np.asarray(self.inlier, bool) & np.isfinite(self.residuals).all(axis=1)
        has_X = np.isfinite(self.X_world).all(axis=1)
        n_rig = max(5 + 6 * (len(self.T_first_cam) - 2), 0)
        n_cam = self.camera.n_free if self.cameras is None else self.cameras.n_free
        n_ba = n_cam + 6 * (n_configs - 1) + n_rig + 3 * int(has_X.sum())
        dof = max(2 * int(inl.sum()) - n_ba, 1)
        return float(np.sqrt(np.sum(self.residuals[inl] ** 2) / dof))

    @property
    def points(self) -> dict[int, np.ndarray]:
        """Reconstructed points ``{point_id: xyz (3,)}`` (only the reconstructed ones)."""
        ok = np.isfinite(self.X_world).all(axis=1)
        return {int(i): x for i, x in zip(self.point_ids[ok], self.X_world[ok], strict=True)}


def with_values(template: Pinhole, values: Pinhole) -> Pinhole:
    """A camera of ``template``'s model and ``free`` selection with ``values``' pinhole values and
    lens coefficients (a lens of another model, or none, starts at zero)."""
    pin = Pinhole(values.fx, values.mu, values.cx, values.cy, values.width, values.height)
    if not isinstance(template, LensCamera):
        return with_pinhole(template, pin)
    same = isinstance(values, LensCamera) and type(values) is type(template)
    coeffs = tuple(values.coeffs) if isinstance(values, LensCamera) and same else ()
    return type(template).from_pinhole(pin, tuple(coeffs), template.free)


# --------------------------------------------------------------------------------- pipeline
def self_calibrate(
    obs: Observations,
    width: int,
    height: int,
    *,
    ref_scores: np.ndarray | None = None,
    scale_markers: tuple[int, int] | None = None,
    scale_distance_m: float | None = None,
    nominal_cam_positions: np.ndarray | None = None,
    rig: bool = True,
    camera: Pinhole | CameraSet | None = None,
    initial: Pinhole | CameraSet | None = None,
    fx_guess: float | None = None,
    mu_guess: float = 1.0,
    fx_bounds: tuple[float, float] | None = None,
    mu_bounds: tuple[float, float] = (0.75, 1.33),
    ransac_px: float = 3.0,
    outlier_px: float = OUTLIER_FLOOR_PX,
    robust_scale_px: float = 1.0,
    max_rounds: int = 5,
    max_nfev: int = 200,
    min_configs: int = 3,
    min_view_points: int = 6,
    max_fx_rel_std_per_px: float = 0.02,
    seed: int = 0,
) -> SelfCalibrationResult:
    """Self-calibrate ``fx``, ``mu``, all camera poses, the rig and the marker corners.

    ``obs``: observations (see :class:`Observations`); ``width``, ``height``: image size (px), the
    principal point is its centre. ``scale_markers=(a, b)`` with ``scale_distance_m`` (distance of
    their centres, m) makes the result metric. ``nominal_cam_positions`` (m, 3) first-camera
    positions (or (m, N, 3) every camera) from the nominal robot model in the robot frame: used
    to choose the sign of ``k`` (:func:`selfcal.estimation.scale_sign.choose_scale_sign`);
    cheirality must then hold. ``rig``: model the camera rig as rigid (default). ``camera``: the
    model and free parameters to estimate (:mod:`selfcal.camera`; its values are ignored): the
    initialisation is the pinhole (principal point at the centre, no distortion), the bundle
    adjustment then frees ``camera.free`` (default: a pinhole with ``fx``, ``mu`` free). A
    :class:`selfcal.camera.CameraSet` gives each camera of the rig its own model and free
    parameters (one intrinsics block per camera); every camera starts at the initialisation's
    pinhole (the rig's cameras are nominally alike).
    ``initial``: a calibrated camera of ``camera``'s model (a ROS CameraInfo's calibration):
    its fx and mu replace the fundamental-matrix estimate, and all its values (principal point,
    lens) start the bundle adjustment, which frees ``camera.free`` from there; a
    :class:`selfcal.camera.CameraSet` of such cameras starts each camera of a set from its own
    (the first camera's fx and mu the initialisation's).
    ``fx_guess``/``mu_guess`` skip the fundamental-matrix estimate of fx/mu (use when it is
    degenerate). Thresholds in px: ``ransac_px`` (epipolar/PnP RANSAC), ``outlier_px`` (minimum
    rejection threshold, :data:`selfcal.calibration.field.adjust.OUTLIER_FLOOR_PX`; the
    actual one is ``max(outlier_px, 4.5 sigma)``), ``robust_scale_px``
    (soft-L1 scale).

    Raises :class:`InsufficientDataError` (too few views/points), :class:`DegenerateConfiguration
    Error` (fx not observable, pure rotation, planar scene), :class:`ScaleMarkerError`,
    :class:`ConvergenceError`; ``ValueError`` for malformed input.
    """
    t_start = time.perf_counter()
    _check_input(obs, width, height, scale_markers, scale_distance_m, rig, min_configs)
    seen = obs
    if initial is not None:
        # initialise on the pixels the initial camera's lens-free, centred pinhole would see, so
        # the pinhole initialisation meets no lens; the adjustment then takes the real pixels
        first: Pinhole = first_camera(initial)  # type: ignore[assignment]
        xn = unproject_views(initial, obs.uv, obs.view)
        c = Pinhole.centered(first.fx, first.mu, width, height)
        seen = dataclasses.replace(obs, uv=np.column_stack([c.fx * xn[:, 0] + c.cx,
                                                            c.fy * xn[:, 1] + c.cy]))  # fmt: skip
        if fx_guess is None:
            fx_guess, mu_guess = first.fx, first.mu
    init = initialise(
        seen,
        width,
        height,
        fx_guess=fx_guess,
        mu_guess=mu_guess,
        fx_bounds=fx_bounds,
        mu_bounds=mu_bounds,
        ransac_px=ransac_px,
        min_view_points=min_view_points,
        seed=seed,
    )
    diag = dict(init.diagnostics)
    rec = gauge(init, obs.layout, rig=rig, ref_scores=ref_scores)
    if initial is not None:
        rec.camera = initial if camera is None else _start(camera, initial, with_values)
    elif camera is not None:
        rec.camera = _start(camera, init.camera, with_pinhole)
    t0 = time.perf_counter()
    fit = adjust(
        rec,
        obs,
        init.active.copy(),
        outlier_px=outlier_px,
        robust_scale_px=robust_scale_px,
        max_rounds=max_rounds,
        max_nfev=max_nfev,
        min_view_points=min_view_points,
        seed=seed,
    )
    diag["t_ba_s"] = time.perf_counter() - t0
    diag["ba_rounds"] = fit.rounds
    diag["ba_nfev"] = fit.nfev
    r_all, _, modelled = residuals(rec, obs)
    rms, cov, cov_unit = _check_fit(
        fit, rec, obs, init, r_all, max_nfev, max_fx_rel_std_per_px, diag
    )
    if scale_markers is not None and scale_distance_m is not None:  # both or neither (checked)
        check_scale_markers_seen(obs, fit.active, scale_markers)
        X_out = np.where(rec.has_X[:, None], rec.X, np.nan)
        sc = scale_from_markers(
            init.point_ids, X_out, scale_markers[0], scale_markers[1], scale_distance_m
        )
        k_abs, d_hat = sc.k, sc.d_hat
    else:
        k_abs, d_hat = 1.0, float("nan")
    sign, sign_choice = 1, None
    if nominal_cam_positions is not None:
        T_world_cam = obs.layout.by_frame(inv_pose(rec.poses()))
        sign, sign_choice = sign_from_nominal(T_world_cam, nominal_cam_positions, k_abs)
    diag["t_total_s"] = time.perf_counter() - t_start
    diag["outlier_threshold_px"] = float(max(outlier_px, 4.5 * rms / np.sqrt(2)))
    res = _result(rec, obs, init, fit, r_all, modelled, rms, cov, cov_unit, sign * k_abs, diag)
    res.is_metric, res.d_hat = scale_markers is not None, d_hat
    res.sign, res.sign_choice = sign, sign_choice
    return res


def _check_input(
    obs: Observations,
    width: int,
    height: int,
    scale_markers: tuple[int, int] | None,
    scale_distance_m: float | None,
    rig: bool,
    min_configs: int,
) -> None:
    """Raise ``TypeError``/``ValueError`` for malformed input, :class:`InsufficientDataError`
    for fewer than ``min_configs`` configurations with observations."""
    if not isinstance(obs, Observations):
        raise UsageTypeError("obs must be an Observations (see Observations.from_corners)")
    if len(obs) and (obs.uv.min(axis=0) < -0.5).any() | (obs.uv[:, 0].max() > width - 0.5) | (
        obs.uv[:, 1].max() > height - 0.5
    ):
        raise InputError(
            f"observations lie outside the {width}x{height} image; check width/height and the "
            "pixel convention (OpenCV, pixel centres at integers)"
        )
    if (scale_markers is None) != (scale_distance_m is None):
        raise InputError("give both scale_markers and scale_distance_m, or neither")
    if rig and obs.n_cameras < 2:
        raise InputError(
            f"rig=True models {obs.n_cameras} camera(s) as a rigid rig, which needs at least two "
            "(its baseline fixes the scale); call with rig=False for one camera"
        )
    cfg_seen = np.unique(obs.config)
    if len(cfg_seen) < min_configs:
        raise InsufficientDataError(
            f"only {len(cfg_seen)} configuration(s) have observations; at least {min_configs} "
            "are needed (the paper's setting uses 6 or more varied viewpoints)"
        )


def _check_fit(
    fit: Adjustment,
    rec: Reconstruction,
    obs: Observations,
    init: InitialReconstruction,
    r_all: np.ndarray,
    max_nfev: int,
    max_fx_rel_std_per_px: float,
    diag: dict,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Reprojection RMS (px) of the final pass's rows (residuals ``r_all`` (k, 2) of every row)
    and the covariance (with the fitted noise and per px) of the camera's free parameters, after
    checking that the adjustment converged, fits the data, keeps the points in front of the
    cameras and determines ``fx``."""
    res, a = fit.bundle, fit.active
    if res.status <= 0:
        raise ConvergenceError(
            f"bundle adjustment did not converge within max_nfev={max_nfev} evaluations "
            f"({res.message}; fx at stop {first_camera(res.camera).fx:.1f} px, initial "  # type: ignore[attr-defined]
            f"{init.camera.fx:.1f} "
            "px); increase max_nfev, or check the observations (outliers, wrong ids); an fx "
            "running away means the views do not constrain it (add configurations with more "
            "varied viewpoints or pass fx_guess)"
        )
    rms = float(np.sqrt(np.mean(np.linalg.norm(r_all[a], axis=1) ** 2)))
    thr = init.threshold_px
    if rms > 3.0 * thr:
        raise ConvergenceError(
            f"bundle adjustment ended with reprojection RMS {rms:.2f} px (> {3 * thr:.1f} px); "
            "the data are inconsistent with one rigid scene and one pinhole camera (lens "
            "distortion? moving markers? wrong ids?)"
        )
    Tv = rec.poses()
    _, pidx = obs.point_index()
    if cheirality_fraction(Tv, rec.X, obs.view[a], pidx[a]) < 0.99:
        raise ConvergenceError(
            "the adjusted reconstruction has points behind the cameras (cheirality violated); "
            "the initialisation converged to a wrong solution -- check the data"
        )
    cov, cov_unit = res.intrinsics_covariance()
    i_fx = first_camera(rec.camera).free.index("fx")  # the first camera's block comes first
    fx_rel_unit = float(np.sqrt(max(cov_unit[i_fx, i_fx], 0.0)) / first_camera(rec.camera).fx)  # type: ignore[attr-defined]
    diag["fx_rel_std_per_px"] = fx_rel_unit
    if not np.isfinite(fx_rel_unit) or fx_rel_unit > max_fx_rel_std_per_px:
        Twc = inv_pose(Tv[np.isfinite(Tv).all(axis=(1, 2))])
        p, d_axes = optical_axes_convergence(Twc)
        dist = float(np.median(np.linalg.norm(Twc[:, :3, 3] - p, axis=1)))
        raise DegenerateConfigurationError(
            f"the views do not determine fx: 1 px of noise would give a relative fx uncertainty "
            f"of {fx_rel_unit:.3g} (> {max_fx_rel_std_per_px}). Optical axes meet within "
            f"{d_axes:.3g} (RMS) of one point at median distance {dist:.3g} (baseline units); "
            "vary viewpoints, aim points and camera roll, and use more configurations"
        )
    return rms, cov, cov_unit


def _result(
    rec: Reconstruction,
    obs: Observations,
    init: InitialReconstruction,
    fit: Adjustment,
    r_all: np.ndarray,
    modelled: np.ndarray,
    rms: float,
    cov: np.ndarray,
    cov_unit: np.ndarray,
    k: float,
    diag: dict,
) -> SelfCalibrationResult:
    """The result with lengths multiplied by the signed scale ``k`` (the caller fills in
    ``is_metric``, ``d_hat``, ``sign`` and ``sign_choice``)."""
    layout = obs.layout
    X = rec.X * k
    Tv = rec.poses()
    Tv[:, :3, 3] *= k
    if rec.rig:
        T_rigs = rec.rig_poses()[1].copy()
        T_rigs[:, :3, 3] *= k
        registered = rec.reg_c
    else:
        try:
            T_rigs = rig_from_views(Tv, rec.reg_v, layout)
        except InsufficientDataError:
            T_rigs = np.full((layout.n_cameras - 1, 4, 4), np.nan)
        registered = layout.frame_all(rec.reg_v)
    T_world_cam = layout.by_frame(inv_pose(Tv)).copy()
    if not rec.rig:
        T_world_cam[~layout.by_frame(rec.reg_v)] = np.nan
    r_out = np.full((len(obs), 2), np.nan)
    r_out[modelled] = r_all[modelled]
    a = fit.active
    cams = rec.camera if isinstance(rec.camera, CameraSet) else None
    cam = first_camera(rec.camera)
    names = list(cam.free)  # the first camera's block comes first in cov
    return SelfCalibrationResult(
        camera=cam,  # type: ignore[arg-type]
        T_world_cam=T_world_cam,
        registered=registered.copy(),
        T_first_cam=np.concatenate([np.eye(4)[None], inv_pose(T_rigs)]),
        point_ids=init.point_ids,
        X_world=np.where(rec.has_X[:, None], X, np.nan),
        residuals=r_out,
        inlier=a.copy(),
        rms_px=rms,
        n_inliers=int(a.sum()),
        n_outliers=int((modelled & ~a).sum()),
        fx_std=_std(cov, names, "fx"),
        mu_std=_std(cov, names, "mu"),
        cov_fx_mu=cov,
        cov_fx_mu_unit=cov_unit,
        ref_config=rec.ref_config,
        is_metric=False,
        scale=float(k),
        d_hat=float("nan"),
        sign=1,
        rig=rec.rig,
        fx_init=float(init.camera_init.fx),
        mu_init=float(init.camera_init.mu),
        diagnostics=diag,
        cameras=cams,
        damping=fit.bundle.damping,
    )


def _start(camera: Pinhole | CameraSet, values: Pinhole | CameraSet, how) -> Pinhole | CameraSet:
    """``how(template, values)`` (:func:`with_values` or :func:`selfcal.camera.with_pinhole`) of
    ``camera``, or of every camera of a set (with its own ``values`` when they are a set)."""
    if isinstance(camera, CameraSet):
        vals = values.cameras if isinstance(values, CameraSet) else (values,) * camera.n_cameras
        cams = tuple(how(c, v) for c, v in zip(camera.cameras, vals, strict=True))
        return CameraSet(cams, camera.names)
    return how(camera, first_camera(values))


def _std(cov: np.ndarray, names: list[str], name: str) -> float:
    """Standard deviation of free parameter ``name`` (NaN when it is held)."""
    if name not in names:
        return float("nan")
    i = names.index(name)
    return float(np.sqrt(max(cov[i, i], 0.0)))
