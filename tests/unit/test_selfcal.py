"""Camera self-calibration (selfcal.calibration.field.self_calibration*): synthetic stereo-rig scenes with known ground truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.calibration.field.adjust import adjust, gauge
from selfcal.calibration.field.initialise import initialise
from selfcal.calibration.field.self_calibration import (
    ConvergenceError,
    DegenerateConfigurationError,
    InsufficientDataError,
    Observations,
    ScaleMarkerError,
    SelfCalibrationError,
    self_calibrate,
)
from selfcal.calibration.field.synthetic import look_at, synthetic_stereo_scene
from selfcal.camera import project
from selfcal.estimation.bundle_adjust import _Problem, bundle_adjust
from selfcal.estimation.focal import focal_from_fundamentals
from selfcal.estimation.pose_models import FreePoses, RigPoses
from selfcal.estimation.scale_sign import cheirality_fraction, choose_scale_sign, rigid_align
from selfcal.target import feature_id, marker_features
from selfcal.transforms import inv_pose, make_pose, pose_from_vec, skew

W, H = 640, 480


def _calibrate(sc, **kw):
    return self_calibrate(
        sc.observations(),
        W,
        H,
        scale_markers=sc.scale_markers,
        scale_distance_m=sc.scale_distance_m,
        **kw,
    )


def _truth_in_result_frame(sc, res):
    """Ground truth expressed in the result's world frame (left camera of ref_config)."""
    G = inv_pose(sc.T_world_cam[res.ref_config, 0])
    X = sc.X_world @ G[:3, :3].T + G[:3, 3]
    return G @ sc.T_world_cam, X[np.searchsorted(sc.point_ids, res.point_ids)]


@pytest.fixture(scope="module")
def noisy30():
    sc = synthetic_stereo_scene(30, seed=11, noise_px=0.5)
    return sc, _calibrate(sc)


# ------------------------------------------------------------------------------- jacobians
def _small_problem(rig: bool, seed=0):
    sc = synthetic_stereo_scene(8, seed=seed)
    obs = sc.observations()
    ids, pidx = obs.point_index()
    rng = np.random.default_rng(seed)
    Tcw = inv_pose(sc.T_world_cam)  # (m, 2, 4, 4)
    G = sc.T_world_cam[0, 0]
    Tcw = Tcw @ G  # world = left camera of config 0
    Xw = sc.X_world[ids] @ inv_pose(G)[:3, :3].T + inv_pose(G)[:3, 3]
    reg = np.ones(8, bool)
    if rig:
        model = RigPoses(Tcw[:, 0], Tcw[0, 1] @ inv_pose(Tcw[0, 0]), reg, 0)
    else:
        model = FreePoses(Tcw.reshape(-1, 4, 4), np.ones(16, bool), 0, 1)
    p = rng.normal(scale=0.05, size=model.n_params)
    prob = _Problem(sc.intrinsics, model, obs.view, pidx, obs.uv, len(ids))
    x = np.concatenate([[810.0, 1.01], p, (Xw + rng.normal(scale=1e-3, size=Xw.shape)).ravel()])
    return prob, x


@pytest.mark.parametrize("rig", [True, False])
def test_analytic_jacobian_matches_finite_differences(rig):
    prob, x = _small_problem(rig)
    J = prob.jac(x).toarray()
    h = 1e-6 * np.maximum(1.0, np.abs(x))
    Jn = np.empty_like(J)
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = h[i]
        Jn[:, i] = (prob.fun(x + e) - prob.fun(x - e)) / (2 * h[i])
    scale = np.abs(Jn).max(axis=0) + 1e-9
    assert np.max(np.abs(J - Jn) / scale) < 1e-5


class _NoJacobian:
    """A pose model without analytic twist Jacobian: exercises the jac_sparsity path."""

    def __init__(self, inner):
        self.inner = inner
        self.n_views, self.n_params = inner.n_views, inner.n_params

    def poses(self, p):
        return self.inner.poses(p)

    def view_columns(self):
        return self.inner.view_columns()

    def view_jacobian(self, p):
        return None


def test_pluggable_pose_model_finite_difference_path_agrees():
    prob, x = _small_problem(True, seed=3)
    model = prob.model
    cam = prob.camera.with_free_values(x[:2])
    kw = dict(view=prob.view, pidx=prob.pidx, uv=prob.uv, camera=cam, loss="linear", tol=1e-12)
    p0, X0 = x[2 : 2 + model.n_params], x[2 + model.n_params :].reshape(-1, 3)
    a = bundle_adjust(model, p0, X0, max_nfev=50, **kw)
    b = bundle_adjust(_NoJacobian(model), p0, X0, max_nfev=400, solver="scipy", **kw)
    assert b.jac is None
    assert abs(a.camera.fx - 800.0) < 1e-6 and abs(b.camera.fx - 800.0) < 1e-4
    np.testing.assert_allclose(b.T_cam_world, a.T_cam_world, atol=1e-6)


# ------------------------------------------------------------------------ focal from F only
def test_focal_from_exact_fundamental_matrices():
    sc = synthetic_stereo_scene(10, seed=5, fx=760.0, mu=1.03)
    K = sc.intrinsics.K
    Kinv = np.linalg.inv(K)
    Tcw = inv_pose(sc.T_world_cam).reshape(-1, 4, 4)
    Fs = []
    for a, b in [(0, 4), (2, 9), (5, 12), (7, 18), (1, 15)]:
        T = Tcw[b] @ inv_pose(Tcw[a])
        Fs.append(Kinv.T @ skew(T[:3, 3]) @ T[:3, :3] @ Kinv)
    est = focal_from_fundamentals(np.array(Fs), sc.intrinsics.cx, sc.intrinsics.cy, W)
    assert abs(est.fx / 760.0 - 1) < 1e-6 and abs(est.mu / 1.03 - 1) < 1e-6


# --------------------------------------------------------------------------- full pipeline
def test_noise_free_recovery_exact():
    sc = synthetic_stereo_scene(12, seed=7, fx=820.0, mu=1.02)
    res = _calibrate(sc)
    assert res.is_metric and res.sign == 1
    assert abs(res.fx / 820.0 - 1) < 1e-6 and abs(res.mu / 1.02 - 1) < 1e-6
    T_true, X_true = _truth_in_result_frame(sc, res)
    reg = res.registered
    assert reg.sum() >= 10
    np.testing.assert_allclose(res.T_world_cam[reg][..., :3, 3], T_true[reg][..., :3, 3], atol=1e-6)
    np.testing.assert_allclose(
        res.T_world_cam[reg][..., :3, :3], T_true[reg][..., :3, :3], atol=1e-6
    )
    ok = np.isfinite(res.X_world).all(axis=1)
    np.testing.assert_allclose(res.X_world[ok], X_true[ok], atol=1e-6)
    np.testing.assert_allclose(res.T_left_right, sc.T_left_right, atol=1e-6)
    np.testing.assert_allclose(res.T_world_cam[res.ref_config, 0], np.eye(4), atol=1e-12)
    assert res.rms_px < 1e-6 and res.n_outliers == 0


def test_half_pixel_noise_30_configs(noisy30):
    sc, res = noisy30
    sigma = 0.5
    # fx within 0.5 % and consistent with its own standard deviation (4 sigma)
    assert abs(res.fx / 800.0 - 1) < 5e-3
    assert abs(res.fx - 800.0) < 4 * res.fx_std
    assert abs(res.mu - 1.0) < 5e-3
    # rms of the 2-D residual norm ~ sigma * sqrt(2) (fewer dof than observations -> a bit less)
    assert 0.8 * sigma * np.sqrt(2) < res.rms_px < 1.1 * sigma * np.sqrt(2)
    T_true, X_true = _truth_in_result_frame(sc, res)
    ok = np.isfinite(res.X_world).all(axis=1)
    err = np.linalg.norm(res.X_world[ok] - X_true[ok], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2e-3  # 2 mm RMS over a 0.3 m field
    reg = res.registered
    cerr = np.linalg.norm(res.T_world_cam[reg][..., :3, 3] - T_true[reg][..., :3, 3], axis=-1)
    assert np.median(cerr) < 2e-3
    assert abs(np.linalg.norm(res.T_left_right[:3, 3]) - 0.06) < 1e-3


def _assert_outliers_rejected(sc, res, noise_px: float) -> int:
    """Every corner ``sc`` displaced is rejected by ``res``, at most 1 % of the others, and the
    residual RMS is the noise's; returns how many were displaced."""
    obs = sc.observations()
    bad = np.zeros(len(obs), bool)
    for cfg, cam, mk, corner in sc.outlier_rows:
        bad |= (obs.config == cfg) & (obs.camera == cam) & (obs.point == feature_id(mk, corner))
    modelled = np.isfinite(res.residuals).all(axis=1)
    assert bad.sum() >= 20
    assert not (res.inlier & bad).any()  # every injected outlier is rejected
    assert (modelled & ~bad & ~res.inlier).sum() <= 0.01 * len(obs)
    assert 0.8 * noise_px * np.sqrt(2) < res.rms_px < 1.1 * noise_px * np.sqrt(2)
    return int(bad.sum())


def test_gross_outliers_rejected():
    sc = synthetic_stereo_scene(30, seed=11, noise_px=0.5, outlier_fraction=0.02)
    res = _calibrate(sc)
    _assert_outliers_rejected(sc, res, 0.5)  # 20 px off
    assert abs(res.fx / 800.0 - 1) < 5e-3 and abs(res.fx - 800.0) < 4 * res.fx_std


def test_pixel_outliers_rejected_on_fine_corners():
    """Corners 2 px off among 0.02 px of noise (a rendered field's marker partly hidden
    behind a raised neighbour, docs/plan.md): every one is rejected (the 1 px floor), which the
    former 3 px floor of the threshold did not do (their residuals stay below it)."""
    sc = synthetic_stereo_scene(30, seed=11, noise_px=0.02, outlier_fraction=0.02, outlier_px=2.0)
    bad = _assert_outliers_rejected(sc, _calibrate(sc), 0.02)
    assert _calibrate(sc, outlier_px=3.0).n_outliers < bad  # the former floor kept some


def test_free_pose_model_matches_rig_model(noisy30):
    sc, res_rig = noisy30
    res = _calibrate(sc, rig=False)
    assert not res.rig
    assert abs(res.fx / 800.0 - 1) < 5e-3
    # the free model has more parameters; both must agree within a few sigma
    assert abs(res.fx - res_rig.fx) < 3 * np.hypot(res.fx_std, res_rig.fx_std) + 1e-9
    np.testing.assert_allclose(res.T_left_right[:3, 3], sc.T_left_right[:3, 3], atol=2e-3)


# -------------------------------------------------------------------------------- the sign
def test_sign_choice_picks_the_right_mirror(noisy30):
    sc, res = noisy30
    reg = res.registered
    C = res.T_world_cam[reg, 0, :3, 3]  # metric, sign +
    rng = np.random.default_rng(1)
    T_robot_world = pose_from_vec(np.array([0.3, -1.2, 0.7, 0.4, 0.1, -0.2]))
    C_true_world = sc.T_world_cam[reg, 0, :3, 3]
    nominal = C_true_world @ T_robot_world[:3, :3].T + T_robot_world[:3, 3]
    nominal += rng.normal(scale=2e-3, size=nominal.shape)  # nominal kinematics, ~2 mm off
    ch = choose_scale_sign(C, nominal)
    assert ch.sign == 1 and not ch.ambiguous and ch.rms_plus_m < 5e-3 < ch.rms_minus_m
    # a reconstruction returned with the opposite sign (X -> -X, t -> -t) must be flipped back
    ch2 = choose_scale_sign(-C, nominal)
    assert ch2.sign == -1 and not ch2.ambiguous
    # cheirality of the chosen sign: points in front of the cameras
    obs = sc.observations()
    ids, pidx = obs.point_index()
    Tcw = inv_pose(res.T_world_cam.reshape(-1, 4, 4))
    use = res.inlier
    assert cheirality_fraction(Tcw, res.X_world, obs.view[use], pidx[use]) == 1.0
    Tm = Tcw.copy()
    Tm[:, :3, 3] *= -1
    assert cheirality_fraction(Tm, -res.X_world, obs.view[use], pidx[use]) == 0.0
    # coplanar trajectory: a point reflection is then a rotation -> ambiguous
    flat = np.c_[rng.uniform(size=(10, 2)), np.zeros(10)]
    assert choose_scale_sign(flat, flat).ambiguous


def test_pipeline_sign_with_nominal_trajectory():
    sc = synthetic_stereo_scene(10, seed=4)
    T_robot_world = pose_from_vec(np.array([0.1, 0.2, -2.0, 0.3, 0.0, 0.1]))
    nominal = sc.T_world_cam[:, 0, :3, 3] @ T_robot_world[:3, :3].T + T_robot_world[:3, 3]
    res = _calibrate(sc, nominal_cam_positions=nominal)
    assert res.sign == 1 and res.sign_choice.sign == 1 and res.scale > 0
    mirrored = nominal * np.array([-1.0, 1.0, 1.0])
    with pytest.raises(SelfCalibrationError, match="mirrored"):
        _calibrate(sc, nominal_cam_positions=mirrored)


def test_rigid_align_recovers_transform():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(8, 3))
    T = make_pose(pose_from_vec(np.array([0.4, -0.3, 1.1, 0, 0, 0]))[:3, :3], [1.0, 2.0, 3.0])
    B = A @ T[:3, :3].T + T[:3, 3]
    T_hat, rms = rigid_align(A, B)
    np.testing.assert_allclose(T_hat, T, atol=1e-12)
    assert rms < 1e-12


# ------------------------------------------------------------------------------ error cases
def test_too_few_views():
    sc = synthetic_stereo_scene(2, seed=1)
    with pytest.raises(InsufficientDataError, match="at least 3"):
        _calibrate(sc)


def test_too_few_shared_points():
    sc = synthetic_stereo_scene(8, seed=1)
    det = {
        (c, cam): {mk + 1000 * (2 * c + cam): v for mk, v in markers.items()}
        for (c, cam), markers in sc.detections.items()
    }
    with pytest.raises(InsufficientDataError, match="shares"):
        self_calibrate(Observations.from_corners(det, 8), W, H)


def test_scale_marker_never_seen():
    sc = synthetic_stereo_scene(10, seed=1)
    with pytest.raises(ScaleMarkerError, match="never observed"):
        self_calibrate(
            sc.observations(), W, H, scale_markers=(sc.scale_markers[0], 999), scale_distance_m=0.1
        )


def test_scale_marker_seen_in_one_view():
    sc = synthetic_stereo_scene(10, seed=1)
    obs = sc.observations()
    a = sc.scale_markers[0]
    of_a = obs.point // 4 == a
    first_view = obs.view[of_a][0]
    keep = ~of_a | (obs.view == first_view)
    with pytest.raises(ScaleMarkerError, match="at least 2 views"):
        self_calibrate(
            obs.subset(keep),
            W,
            H,
            scale_markers=sc.scale_markers,
            scale_distance_m=sc.scale_distance_m,
        )


def test_optical_axes_through_one_point_is_reported():
    # every view aims both (toed-in) cameras at the field centre from the same distance
    sc = synthetic_stereo_scene(20, seed=2, fixate=True, vergence_distance_m=0.3)
    with pytest.raises(DegenerateConfigurationError, match="optical axes pass through one point"):
        _calibrate(sc)
    # the multi-view bundle adjustment still determines fx from a rough guess
    res = _calibrate(sc, fx_guess=900.0)
    assert abs(res.fx / 800.0 - 1) < 1e-6


def test_planar_marker_field_is_reported():
    sc = synthetic_stereo_scene(10, seed=1, relief_m=0.0)
    with pytest.raises(DegenerateConfigurationError, match="coplanar") as info:
        _calibrate(sc)
    # a planar target declared as a field: the fix says to declare the board
    assert "declare the board with a target TOML" in str(info.value.fix)


def test_pure_rotation_is_reported():
    rng = np.random.default_rng(0)
    C = np.array([0.02, -0.01, 0.3])
    T = np.stack(
        [
            look_at(C, np.r_[rng.uniform(-0.08, 0.08, 2), 0.04], rng.uniform(-0.5, 0.5))
            for _ in range(12)
        ]
    )
    sc = synthetic_stereo_scene(12, seed=3, T_world_left=T)
    obs = sc.observations()
    left_only = obs.subset(obs.camera == 0)  # a single camera rotating about its centre
    with pytest.raises(DegenerateConfigurationError, match="pure rotation"):
        self_calibrate(left_only, W, H)
    # with the right camera the rig baseline moves the right camera centre: solvable
    res = self_calibrate(obs, W, H)
    assert abs(res.fx / 800.0 - 1) < 1e-6


def test_non_convergence_raises():
    sc = synthetic_stereo_scene(10, seed=1, noise_px=0.5)
    with pytest.raises(ConvergenceError, match="max_nfev"):
        _calibrate(sc, max_nfev=2)


def test_observations_outside_image_rejected():
    sc = synthetic_stereo_scene(6, seed=1)
    with pytest.raises(ValueError, match="outside"):
        self_calibrate(sc.observations(), 320, 240)


def test_projection_consistency_of_synthetic_scene():
    # the generator uses selfcal.camera.project; check one detection against it directly
    sc = synthetic_stereo_scene(3, seed=9)
    (cfg, cam), markers = next(iter(sc.detections.items()))
    mk, uv = next(iter(markers.items()))
    Tcw = inv_pose(sc.T_world_cam[cfg, cam])
    np.testing.assert_allclose(uv, project(sc.intrinsics, Tcw, sc.X_world[marker_features(mk)]))


def test_the_camera_stage_adjusts_no_more_often_than_it_needs():
    """A robust round that keeps exactly the rows it was given is followed by the final
    least-squares pass (a second robust round would solve the same problem again): the
    adjustment started again from its own result and rows takes one robust round."""
    sc = synthetic_stereo_scene(12, seed=5, noise_px=0.5)
    obs = sc.observations()
    init = initialise(obs, W, H)
    # the initial reconstruction adjusted at 4, 8, 16 ... registered views and left the views
    # registered after the last of those to the camera stage's adjustment (no final pass)
    n_reg = int(init.registered.sum())
    assert init.n_ba == int(np.log2(n_reg)) - 1 and n_reg > 2 ** int(np.log2(n_reg))
    rec = gauge(init, obs.layout, rig=True)
    first = adjust(rec, obs, init.active.copy())
    again = adjust(rec, obs, first.active.copy())
    assert again.rounds == 2
    np.testing.assert_array_equal(again.active, first.active)
    assert abs(again.bundle.cost - first.bundle.cost) <= 1e-9 * first.bundle.cost


def test_a_robust_round_that_drops_rows_is_followed_by_the_checked_final_pass():
    """A robust round that drops rows (here a corner moved 5 px, handed to the adjustment as an
    inlier) is followed by the final least-squares pass over the rows it keeps, whose own fit
    classifies them again: it keeps them, so the adjustment ends after two solves (a second
    robust round on those rows came first until session 29). The fit is the one an adjustment
    started again from its own result and rows ends with."""
    sc = synthetic_stereo_scene(12, seed=5, noise_px=0.5)
    obs = sc.observations()
    init = initialise(obs, W, H)
    row = int(np.flatnonzero(init.active)[50])
    uv = obs.uv.copy()
    uv[row] += 5.0
    moved = dataclasses.replace(obs, uv=uv)
    rec = gauge(init, obs.layout, rig=True)
    first = adjust(rec, moved, init.active.copy())
    assert not first.active[row] and first.rounds == 2
    again = adjust(rec, moved, first.active.copy())
    assert again.rounds == 2
    np.testing.assert_array_equal(again.active, first.active)
    assert abs(again.bundle.cost - first.bundle.cost) <= 1e-9 * first.bundle.cost
