"""The engine and scipy.optimize.least_squares reach the same minimum on the project's problems.

The default scenario (analytic path, 12 postures) is calibrated once; the final least-squares
passes of the bundle adjustment (stereo rig, intrinsics, points) and of the one-step kinematic
identification (MCPC chain, rig, joint corrections, points, scale distance, priors) are captured
as they are handed to the engine, moved away from their minimum, and solved again by the engine
(dense, sparse and Schur linear solvers) and by scipy's trust-region least squares.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

import selfcal.calibration.field.joint_refine as joint_refine
import selfcal.estimation.bundle_adjust as bundle_adjust
from selfcal.benchmarks.speed.measure import off_minimum as _perturbed
from selfcal.calibration.field.calibrate import calibrate
from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire
from selfcal.solver import Problem, SolverOptions, solve

# measured <= 5.7e-14 (rounding; the engine stops at a cost change of 1e-12 relative, and the
# captured problems follow the floating-point path of the calibration that captures them: 1.5e-14
# before the solver's stop at the cost's rounding); issue 11 asks for 1e-9
REL_COST = 1.5e-13
REL_STEP = 2e-10  # one step, each linear solver against dense LU: measured <= 6.1e-11


@pytest.fixture(scope="module")
def captured(tmp_path_factory):
    """``{"bundle": Problem, "joint": Problem}``: the last plain least-squares pass of each."""
    root = tmp_path_factory.mktemp("equiv")
    s = load_scenario(overrides={"noise": {"render": False}, "trajectory": {"poses": 12}})
    run_acquire(s, root, quiet=True)
    seen: dict[str, list] = {"bundle": [], "joint": []}
    real = bundle_adjust.solve

    def spy(kind):
        def wrapped(problem, options=None, plans=None):
            seen[kind].append(problem)
            return real(problem, options, plans)

        return wrapped

    mp = pytest.MonkeyPatch()
    mp.setattr(bundle_adjust, "solve", spy("bundle"))
    mp.setattr(joint_refine, "solve", spy("joint"))
    try:
        calibrate(root)
    finally:
        mp.undo()
    return {k: v[-1] for k, v in seen.items()}


def _scipy_cost(problem: Problem) -> float:
    res = least_squares(
        problem.residual_vector,
        problem.x0,
        jac=lambda x: problem.jacobian(x).toarray(),
        method="trf",
        tr_solver="exact",
        x_scale="jac",
        ftol=1e-15,
        xtol=1e-15,
        gtol=1e-15,
        max_nfev=200,
    )
    assert res.status > 0, res.message
    return float(res.cost)


@pytest.mark.parametrize("kind", ["bundle", "joint"])
def test_engine_and_scipy_reach_the_same_cost(captured, kind):
    prob = _perturbed(captured[kind], seed=1)
    ref = _scipy_cost(prob)
    costs = {}
    for linear in ("dense", "sparse", "schur"):
        opt = SolverOptions(tol=1e-12, linear_solver=linear, eliminate="poses")
        res = solve(prob, opt)
        assert res.converged, res.message
        assert res.linear_solver == linear
        costs[linear] = res.cost
    start = 0.5 * float(np.sum(prob.residual_vector(prob.x0) ** 2))
    assert start > 10 * ref  # the start is genuinely away from the minimum
    for linear, c in costs.items():
        assert abs(c - ref) <= REL_COST * ref, (kind, linear, c, ref)


@pytest.mark.parametrize("kind", ["bundle", "joint"])
def test_schur_elimination_of_the_poses_is_the_same_step(captured, kind):
    """One iteration with each linear solver gives the same iterate (Schur is exact algebra)."""
    prob = _perturbed(captured[kind], seed=2)
    assert prob.parameters["poses"].instance is not None
    xs = {
        lin: solve(prob, SolverOptions(max_iterations=1, linear_solver=lin, eliminate="poses")).x
        for lin in ("dense", "sparse", "schur")
    }
    step = np.linalg.norm(xs["dense"] - prob.x0)
    assert step > 0
    for lin in ("sparse", "schur"):
        assert np.linalg.norm(xs[lin] - xs["dense"]) <= REL_STEP * step, lin
