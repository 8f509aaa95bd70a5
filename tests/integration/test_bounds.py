"""Cramer-Rao bounds (selfcal.calibration.field.bounds) against a brute-force Fisher matrix and a small Monte Carlo.

1. On a tiny problem (7 postures, the default marker field) the bounds computed from the joint
   refinement's sparse analytic Jacobian equal those of a dense Fisher matrix built by central
   differences of an independent forward model (own rig and read-back parametrisation, own
   reference-frame map), to 1e-3 relative.
2. 8 noise draws of one truth (analytic path, 12 postures): the one-step method's achieved
   tool-tip RMS / bound lies in the interval an efficient estimator gives with 8 draws (chi-square
   with 8 x nu degrees of freedom, nu from the bound's eigenvalues; two-sided 99.9 %), widened by
   15 % for the small-sample bias of a nonlinear estimator with 12 postures; the two-stage
   method's is larger; the bound evaluated at the two-stage estimate equals the one at the joint
   estimate (a property of the data) to 3 %.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from selfcal.calibration.field.bounds import (
    aligned_error_dof,
    aligned_rms_from_covariance,
    cramer_rao,
)
from selfcal.calibration.field.joint_refine import encoder_sigma
from selfcal.config.scenario import load_scenario
from selfcal.kinematics.alignment import express_in_frame, minimal_difference
from selfcal.kinematics.forward import fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import minimal_indices
from selfcal.kinematics.trajectory import plan_postures
from selfcal.studies.montecarlo.plan_comparison import sim_fisher_setup
from selfcal.transforms import inv_pose, kabsch, pose_from_vec, skew


@pytest.fixture(scope="module")
def tiny():
    from selfcal.acquisition.backends import planning_inputs
    from selfcal.acquisition.simulator_setup import sim_setup

    s = load_scenario(None, {"noise": {"render": False}, "target": {"markers": 8}})
    setup = sim_setup(s)
    inp = planning_inputs(s)
    q = plan_postures(
        inp["robot"],
        inp["model_cam"],
        inp["rig"],
        inp["points_world"],
        7,
        seed=3,
        min_visible=6,
        normals_world=inp["normals_world"],
    )
    st = sim_fisher_setup(
        setup,
        q,
        0.2,
        pixel_sigma_px=0.5,
        joint_sigma=encoder_sigma(setup.robot) * 20,  # large enough to matter
        ref_config=2,
    )
    # a soft scale constraint keeps the dense brute-force inverse well conditioned
    return dataclasses.replace(st, scale_sigma_m=1e-4, held=("gamma5",)), setup


def _brute_force(st):
    """Dense Fisher matrix by central differences of an independent forward model."""
    model = st.model
    idx = minimal_indices(model.joint_types)
    from selfcal.kinematics.mcpc import param_names

    names = param_names(idx)
    from selfcal.calibration.field.joint_refine import choose_gauge

    held = set(choose_gauge(model).held) | set(st.held)
    free_idx = idx[[nm not in held for nm in names]]
    m, n = st.q.shape
    k, P = len(free_idx), len(st.X_world)
    T_rl0 = inv_pose(st.T_left_right)
    js = np.asarray(st.joint_sigma)
    z0 = np.concatenate(
        [
            [st.fx, st.mu],
            model.params.reshape(-1)[free_idx],
            np.zeros(6 + m * n),
            st.X_world.ravel(),
        ]
    )

    def unpack(z):
        flat = model.params.reshape(-1).copy()
        flat[free_idx] = z[2 : 2 + k]
        mdl = model.with_params(flat)
        T_rl = pose_from_vec(z[2 + k : 8 + k]) @ T_rl0  # another rig parametrisation
        dq = z[8 + k : 8 + k + m * n].reshape(m, n)
        X = z[8 + k + m * n :].reshape(P, 3)
        return z[0], z[1], mdl, T_rl, dq, X

    def residuals(z):
        fx, mu, mdl, T_rl, dq, X = unpack(z)
        K = np.array([[fx, 0, st.camera.cx], [0, fx * mu, st.camera.cy], [0, 0, 1.0]])
        T_lw = inv_pose(fk_tool(mdl, st.q + dq))
        T_cw = np.stack([T_lw, T_rl @ T_lw], axis=1).reshape(-1, 4, 4)
        Xc = np.einsum("kij,kj->ki", T_cw[st.view, :3, :3], X[st.pidx]) + T_cw[st.view, :3, 3]
        uvw = Xc @ K.T  # the pinhole written out: independent of selfcal.camera
        uv = uvw[:, :2] / uvw[:, 2:]
        ca = X[st.scale_points[0]].mean(axis=0)
        cb = X[st.scale_points[1]].mean(axis=0)
        scale = (np.linalg.norm(ca - cb) - st.scale_distance_m) / st.scale_sigma_m
        return np.concatenate(
            [uv.ravel() / st.pixel_sigma_px, [scale / st.pixel_sigma_px], (dq / js).ravel()]
        )

    def num_jac(f, z, h):
        cols = []
        for j in range(len(z)):
            e = np.zeros(len(z))
            e[j] = h[j]
            cols.append((f(z + e) - f(z - e)) / (2 * h[j]))
        return np.stack(cols, axis=1)

    h = np.maximum(np.abs(z0), 1.0) * 1e-6
    J = num_jac(residuals, z0, h)
    C = np.linalg.inv(J.T @ J)

    def ref_params(z):
        _, _, mdl, _, dq, _ = unpack(z)
        T = fk_tool(mdl, (st.q[st.ref_config] + dq[st.ref_config])[None])[0]
        return minimal_difference(express_in_frame(mdl, inv_pose(T), like=model), model)

    G = num_jac(ref_params, z0, h)
    return C, G, free_idx, unpack, z0, h


def test_bound_matches_brute_force_fisher(tiny):
    st, setup = tiny
    cr = cramer_rao(st)
    C, G, free_idx, unpack, z0, h = _brute_force(st)
    # parameters in the reference-camera frame
    std_bf = np.sqrt(np.diag(G @ C @ G.T))
    est = np.isfinite(cr.std_ref)
    assert est.sum() == 25
    np.testing.assert_allclose(cr.std_ref[est], std_bf[est], rtol=1e-3)
    np.testing.assert_allclose([cr.fx_std, cr.mu_std], np.sqrt(np.diag(C)[:2]), rtol=1e-3)
    # the aligned tool-tip RMS bound at validation-like postures
    rng = np.random.default_rng(0)
    qv = setup.robot.home + rng.uniform(-0.5, 0.5, (12, st.model.n))
    T_cam_tip = inv_pose(setup.robot.T_flange_cam)

    def tips(z):
        _, _, mdl, _, _, _ = unpack(z)
        return (fk_tool(mdl, qv) @ T_cam_tip)[:, :3, 3].ravel()

    cols = []
    for j in range(len(z0)):
        e = np.zeros(len(z0))
        e[j] = h[j]
        cols.append((tips(z0 + e) - tips(z0 - e)) / (2 * h[j]))
    Jt = np.stack(cols, axis=1)
    bf = aligned_rms_from_covariance(tips(z0).reshape(-1, 3), Jt @ C @ Jt.T)
    assert cr.aligned_tool_rms(qv, T_cam_tip) == pytest.approx(bf, rel=1e-3)
    # the aligned metric is gauge invariant: the reference-frame covariance gives the same
    idx = minimal_indices(cr.model_ref.joint_types)
    T = fk_tool(cr.model_ref, qv)
    Jb = identification_jacobian(cr.model_ref, qv)[:, :, idx]
    pt = T_cam_tip[:3, 3]
    Jp = (T[:, :3, :3] @ (Jb[:, :3] - skew(pt) @ Jb[:, 3:])).reshape(-1, idx.size)
    P_ref = (T @ T_cam_tip)[:, :3, 3]
    rms_ref = aligned_rms_from_covariance(P_ref, Jp @ cr.cov_ref @ Jp.T)
    assert rms_ref == pytest.approx(bf, rel=1e-3)


def test_aligned_error_dof_matches_sampled_alignments(tiny):
    """Satterthwaite's nu = 2 E[q]^2 / Var[q] of the aligned squared error q, checked against
    draws of the predicted points' errors aligned by Kabsch (not by the projection the function
    uses): sampled mean within 3 % of the bound's trace, sampled nu within 10 % (4000 draws; the
    sampling error of a variance with nu ~ 2 is ~5 %)."""
    st, setup = tiny
    cr = cramer_rao(st)
    rng = np.random.default_rng(1)
    qv = setup.robot.home + rng.uniform(-0.5, 0.5, (12, st.model.n))
    P, S = cr.tool_points(qv, inv_pose(setup.robot.T_flange_cam))
    nu = aligned_error_dof(P, S)
    scale = 1e-3 / np.sqrt(np.trace(S) / len(P))  # ~1 mm errors: the alignment stays linear
    w, V = np.linalg.eigh(S * scale**2)  # S has rank <= free parameters: no Cholesky
    L = V * np.sqrt(np.clip(w, 0.0, None))
    q = np.empty(4000)
    for i in range(len(q)):
        B = P + (L @ rng.standard_normal(len(S))).reshape(-1, 3)
        T = kabsch(B, P)
        q[i] = np.sum((B @ T[:3, :3].T + T[:3, 3] - P) ** 2)
    assert q.mean() == pytest.approx(
        len(P) * (aligned_rms_from_covariance(P, S) * scale) ** 2, rel=0.03
    )
    assert 2 * q.mean() ** 2 / q.var() == pytest.approx(nu, rel=0.10)


@pytest.fixture(scope="module")
def mc_rows(paper_montecarlo_12):
    """8 draws of 12 postures (tests/conftest.py; tests/integration/test_cluster.py compares
    three of them with the same draws on a cluster)."""
    return paper_montecarlo_12


@pytest.mark.slow
def test_monte_carlo_ratio_is_statistically_consistent_with_the_bound(mc_rows):
    rows, summary = mc_rows
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == 8, [r["status"] for r in rows]
    nu = float(np.median([r["dof_tip"] for r in ok]))
    N = len(ok)
    lo = np.sqrt(chi2.ppf(0.0005, N * nu) / (N * nu))
    hi = np.sqrt(chi2.ppf(0.9995, N * nu) / (N * nu))
    ratio = summary["joint"]["tool_tip_ratio"]
    print(f"joint ratio {ratio:.3f}, efficient interval [{lo:.3f}, {hi:.3f}] (nu {nu:.1f})")
    assert lo <= ratio <= 1.15 * hi
    assert summary["two_stage"]["tool_tip_ratio"] > ratio
    # the bound is a property of the data: the same at the two-stage estimate
    for r in ok:
        assert r["bound_tip_two_stage_mm"] == pytest.approx(r["bound_tip_rms_mm"], rel=0.03)
