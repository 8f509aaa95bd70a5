"""The touch-probe term (selfcal.terms.probe) on the one solver, without images.

A simulated ER-4u whose joint offsets differ from the nominal by 0.2-0.5 deg; its probe tip (on the
flange, off every axis) touches points known in a fixture's frame (the touches' repeatability
0.02 mm per coordinate). The term's blocks alone, with the fixture frame and the tip given,
calibrate the chain (the minimal parameters a point determines): the tip predicted at held-out
joints from the nominal chain is millimetres off, from the calibrated one at the touches' noise.
The analytic Jacobian (chain, fixture frame and tip unknown) matches finite differences.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.solver import ParameterBlock, Problem, SolverOptions, scaled_rank, solve
from selfcal.terms.base import TermContext, TermSolution, term_blocks
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.transforms import pose_from_vec

SIGMA_M = 2e-5
TIP = np.array([0.012, -0.018, 0.065])  # m, in the flange frame
T_FIXTURE_WORLD = pose_from_vec([0.3, -0.2, 1.1, 0.5, -0.3, 0.1])


def _case(seed: int = 3):
    robot = load_robot("er4u-paper")
    nominal = nominal_mcpc(robot)
    offsets = np.radians([0.3, -0.4, 0.25, -0.35, 0.5])
    truth = dataclasses.replace(nominal, joint_offsets=nominal.joint_offsets + offsets)
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    q = lo + (hi - lo) * (0.15 + 0.7 * rng.random((60, robot.n)))
    qv = lo + (hi - lo) * (0.15 + 0.7 * rng.random((20, robot.n)))

    def tips(model, qq):
        T = fk_tool(model, qq)
        return T[:, :3, :3] @ TIP + T[:, :3, 3]

    x = tips(truth, q)
    p = x @ T_FIXTURE_WORLD[:3, :3].T + T_FIXTURE_WORLD[:3, 3]
    p += rng.normal(0.0, SIGMA_M, p.shape)
    return robot, nominal, truth, q, qv, p, tips


def _position_indices(nominal):
    """The minimal parameters a point on the tool determines (not the tool's orientation)."""
    idx = minimal_indices(nominal.joint_types)
    tool_rot = 6 * nominal.n + np.arange(3)  # alpha_n, beta_n, gamma_n
    return idx[~np.isin(idx, tool_rot)]


def test_touches_of_known_points_calibrate_the_chain():
    robot, nominal, truth, q, qv, p, tips = _case()
    term = ProbeTerm(q, p, np.arange(len(q)), SIGMA_M, T_FIXTURE_WORLD, TIP)
    free = _position_indices(nominal)
    ctx = TermContext(nominal, free, "mcpc")
    built = term.build(ctx)
    residuals, params = term_blocks([built])
    prob = Problem([ParameterBlock("mcpc", nominal.params.reshape(-1)[free]), *params], residuals)
    rank = scaled_rank(prob.jacobian(prob.x0))[1]
    assert rank == prob.n  # every unknown determined by the touches
    sol = solve(prob, SolverOptions(tol=1e-12, max_iterations=50))
    assert sol.status > 0
    flat = nominal.params.reshape(-1).copy()
    flat[free] = sol.values["mcpc"]
    fitted = nominal.with_params(flat)
    err = lambda m: np.linalg.norm(tips(m, qv) - tips(truth, qv), axis=1)  # noqa: E731
    rms = lambda e: 1e3 * float(np.sqrt(np.mean(e**2)))  # noqa: E731
    e_nom, e_fit = rms(err(nominal)), rms(err(fitted))
    print(f"held-out tip error RMS: nominal {e_nom:.3f} mm, calibrated {e_fit:.4f} mm")
    assert e_nom > 2.0  # the offsets move the tip by millimetres (measured 3.59 mm)
    assert e_fit < 0.05  # of the touches' noise (0.035 mm 3-D); measured 0.018 mm
    report = term.report(built, TermSolution(sol.values, sol.residuals, fitted, fitted, ctx))
    sec = report.section
    assert isinstance(sec, ProbeSection) and sec.T_fixture_world_m is None
    assert sec.touches == sec.points == len(q) and np.allclose(sec.tip_mm, 1e3 * TIP)
    # the fit is the noise: 3-D RMS of 0.02 mm per coordinate is 0.035 mm, less the dof
    assert 0.5 * np.sqrt(3) * 1e3 * SIGMA_M < sec.rms_mm < 1.5 * np.sqrt(3) * 1e3 * SIGMA_M
    assert ProbeSection.from_json(_fields(sec.to_json())).to_json() == sec.to_json()


def _fields(doc):
    from selfcal.io.jsonfile import Fields

    return Fields(doc, "test", "")


def test_the_jacobian_of_chain_fixture_and_tip_matches_finite_differences():
    robot, nominal, truth, q, qv, p, tips = _case()
    term = ProbeTerm(q[:8], p[:8], np.arange(8), SIGMA_M)  # fixture and tip unknown
    free = _position_indices(nominal)
    residuals, params = term_blocks([term.build(TermContext(nominal, free, "mcpc", 0.5))])
    assert [b.name for b in params] == ["probe_fixture", "probe_tip"]
    prob = Problem([ParameterBlock("mcpc", nominal.params.reshape(-1)[free]), *params], residuals)
    x0 = prob.x0 + np.random.default_rng(1).normal(0.0, 1e-3, prob.n)
    J = prob.jacobian(x0).toarray()
    h = 1e-7
    Jn = np.stack(
        [(prob.residual_vector(x0 + h * e) - prob.residual_vector(x0 - h * e)) / (2 * h)
         for e in np.eye(prob.n)], axis=1,
    )  # fmt: skip
    assert np.abs(J - Jn).max() <= 1e-5 * np.abs(Jn).max()


def test_bad_touches_are_refused_naming_the_cause():
    q = np.zeros((3, 5))
    with pytest.raises(InputError, match="outside the 2 known points"):
        ProbeTerm(q, np.zeros((2, 3)), np.array([0, 1, 2]))
    with pytest.raises(InputError, match="3 joint rows need as many"):
        ProbeTerm(q, np.zeros((2, 3)), np.array([0, 1]))
    with pytest.raises(InputError, match="noise must be positive"):
        ProbeTerm(q, np.zeros((3, 3)), np.arange(3), sigma_m=0.0)
