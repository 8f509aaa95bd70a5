"""What limits the drift check's power, per draw (selfcal.benchmarks.drift.parts --per-draw,
issue #29): its tests recomputed from the whitened Gram matrix of the candidates' columns and
the residuals are the check's own, and the statistics it reads against their null are."""

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2, norm

from selfcal.benchmarks.drift.parts import _rounded_power, _tests, per_draw_summary
from selfcal.calibration.drift.covariance import change_information, view_covariance
from selfcal.calibration.drift.images import image_drift_check
from selfcal.calibration.drift.views import view_jacobians
from selfcal.camera import camera_model
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose


@pytest.fixture(scope="module")
def scene():
    """Five eye-in-hand views of 12 points of the nominal ER-4u with the robot file's joint
    read-back noise, a small estimation and camera covariance: the views and ``C``."""
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    cols = minimal_indices(model.joint_types)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(cols.size, cols.size)) * 2e-5
    em = ToolErrorModel(model, np.eye(4), cols, A @ A.T, 0.0, 0.0, np.eye(4))
    free = ("fx", "mu", "cx", "cy", "k1", "k2")
    cam = camera_model("opencv", fx=800.0, mu=1.0, cx=320.0, cy=240.0, width=640, height=480,
                       coeffs={"k1": -0.25, "k2": 0.1}, free=free)  # fmt: skip
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (5, robot.n)) * 0.5
    js = np.array(robot.encoder.read_back_sigma)
    views = []
    for T in fk_tool(model, q):
        x = np.c_[rng.uniform(-0.15, 0.15, (12, 2)), rng.uniform(0.3, 0.5, 12)]
        T_cam_board = inv_pose(T)
        X = (x - T_cam_board[:3, 3]) @ T_cam_board[:3, :3]
        views.append(view_jacobians(em, cam, q[len(views)], X, cam.project(x), eye_to_hand=False,
                                    pixel_sigma_px=0.2, joint_sigma_rad=js))  # fmt: skip
    B = np.diag([0.3, 1e-4, 0.3, 0.3, 1e-3, 1e-3]) @ rng.normal(size=(len(free),) * 2) / 2.5
    C = np.zeros((cols.size + len(free),) * 2)
    C[: cols.size, : cols.size] = em.covariance
    C[cols.size :, cols.size :] = B @ B.T
    return views, C


def _with(views, r):
    at = np.cumsum([0] + [len(v.r) for v in views])
    return [dataclasses.replace(v, r=r[at[i] : at[i + 1]]) for i, v in enumerate(views)]


def test_the_per_draw_tests_are_the_checks_own(scene):
    """Each test's p-value from the Gram matrix, Bonferroni-combined, is the check's p-value, on
    residuals of its own covariance and with a mount shift added."""
    views, C = scene
    L = np.linalg.cholesky(view_covariance(C, views))
    rng = np.random.default_rng(2)
    G = np.concatenate([v.tool[:, :3] for v in views])
    for shift in (np.zeros(3), np.array([2e-4, -1e-4, 1e-4])):
        r = L @ rng.normal(size=len(L)) + G @ shift
        got = _with(views, r)
        tests = _tests(C, got)
        assert len(tests) == 11  # the omnibus, the camera, 4 of the mounts, 5 joints
        check = image_drift_check(C, got, eye_to_hand=False)
        assert min(1.0, len(tests) * min(tests.values())) == pytest.approx(check.p_value,
                                                                            rel=1e-6)  # fmt: skip


def test_the_statistics_read_against_their_null_have_it(scene):
    """Residuals of the check's own covariance: their projection on a shift's whitened pixels is
    a standard normal and their chi-square on the mount's 3 axes has 3 degrees of freedom
    (2000 draws: the per-draw summary's null lines read this)."""
    views, C = scene
    L = np.linalg.cholesky(view_covariance(C, views))
    G = np.concatenate([v.tool[:, :3] for v in views])
    x = np.array([1e-4, 1e-4, -1.5e-4])
    rng = np.random.default_rng(3)
    z, axes = [], []
    for r in (L @ rng.normal(size=(len(L), 2000))).T:
        M = change_information(C, views, np.c_[G, r])
        F, y = M[:3, :3], M[:3, 3]
        z.append(x @ y / np.sqrt(x @ F @ x))
        axes.append(y @ np.linalg.solve(F, y))
    assert np.mean(z) == pytest.approx(0.0, abs=0.07)
    assert np.var(z) == pytest.approx(1.0, abs=0.1)
    assert np.mean(axes) == pytest.approx(3.0, abs=0.2)
    assert np.mean(np.array(axes) > chi2.isf(0.05, 3)) == pytest.approx(0.05, abs=0.015)


def test_the_rounded_read_back_power_is_the_bounded_distributions():
    """All of the projection's noise one joint's rounding (uniform over a count, the ER-4u's
    base joint): the test's critical value is the uniform's 99th percentile and its power the
    uniform's share beyond it less the shift; no read-back table (exact joints): the normal
    test's power."""
    arm = load_robot("er4u-paper")
    q = np.zeros((1, arm.n))
    w = np.zeros((1, arm.n))
    w[0, 0] = 1.0 / arm.encoder.read_back_sigma[0]  # z = the rounding error / its sigma
    half = np.sqrt(3.0)
    crit = half * (1 - 2 * 0.01)
    for lam in (0.5, 1.0, 2.0):
        want = np.clip((half - (crit - lam)) / (2 * half), 0.0, 1.0)
        got = _rounded_power(w, lam**2, q, arm, np.random.default_rng(1))
        assert got == pytest.approx(want, abs=0.012)
    exact = dataclasses.replace(arm, encoder=None)
    got = _rounded_power(w, 4.0, q, exact, np.random.default_rng(1))
    assert got == pytest.approx(norm.sf(norm.isf(0.01) - 2.0), abs=0.01)


def test_the_summary_reads_its_rows():
    rows = [{"corners": 300, "signal_px": 0.25, "lam2": l2, "z": z, "axes_null": 3.0,
             "p_unchanged": 0.5, "p_shifted": p, "smallest": "hand-eye translation",
             "tests": 11, "told_direction": 0.96, "told_direction_rounded": 0.95,
             "read_back_share": 0.5, "told_size": 0.9, "told_axes": 0.88,
             "axes_bonferroni": 0.77, "noise_px": 0.2, "noise_dof": 4000, "views": 5}
            for l2, z, p in ((20.0, -1.0, 0.001), (30.0, 1.0, 0.5))]  # fmt: skip
    text = per_draw_summary(rows, "test")
    assert "| the check: 'changed' on unchanged data / the shift found | 0.0 % / 50.0 % |" in text
    assert "| hand-eye translation 1 |" in text
    assert "96.0 % / 90.0 % / 88.0 % / 77.0 % |" in text
    assert "| 0.000 / 1.000 |" in text
