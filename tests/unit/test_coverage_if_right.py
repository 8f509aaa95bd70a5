"""The coverage a right prediction would show (selfcal.benchmarks.tracker.accuracy, issue #29):
the board and tracker Monte Carlos' yardstick for their pooled coverage."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.tracker.accuracy import coverage_if_right, right_range
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.robot.definition import load_robot


def _model(covariance_scale: float, model_error_m: float, model_error_rad: float | None):
    robot = load_robot("ur5e")
    model = nominal_mcpc(robot)
    cols = minimal_indices(model.joint_types)
    C = covariance_scale * np.eye(cols.size)
    rng = np.random.default_rng(3)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (64, robot.n))
    em = ToolErrorModel(model, np.eye(4), cols, C, model_error_m, model_error_rad)
    return em, q


def test_an_isotropic_model_error_alone_is_covered_95_percent_of_the_time():
    """With no parameter covariance, the errors are the model error, isotropic and drawn
    independently at every joint vector: the 95 % bound is exact there (chi with 3 degrees of
    freedom), so 400 x 64 draws cover 95 % within 4 standard errors (0.0014), and every draw's
    coverage is a binomial share of 64 points."""
    em, q = _model(0.0, 1e-4, 2e-4)
    got = coverage_if_right(em, q, seed=1)
    assert got.shape == (2, 400)
    assert np.mean(got[0]) == pytest.approx(0.95, abs=0.0045)
    assert np.mean(got[1]) == pytest.approx(0.95, abs=0.0045)
    assert np.std(got[0]) == pytest.approx(np.sqrt(0.95 * 0.05 / 64), rel=0.15)


def test_one_parameter_error_moves_every_joint_vector_at_once():
    """The parameters' error is one draw for the whole workspace: with the covariance alone
    the coverage of one draw spreads more than independent points' would (2.5x the binomial
    spread here), and its mean is still about 95 % (Satterthwaite's quantile, not exact for an
    anisotropic covariance); the same seed gives the same draws, no orientation gives nan."""
    em, q = _model(1e-8, 0.0, None)
    got = coverage_if_right(em, q, seed=2)
    assert np.mean(got[0]) == pytest.approx(0.95, abs=0.02)
    assert np.std(got[0]) > 2 * np.sqrt(0.95 * 0.05 / 64)  # 2.5x measured
    assert np.all(np.isnan(got[1]))
    assert np.array_equal(got[0], coverage_if_right(em, q, seed=2)[0])


def test_right_range_pools_the_draws_index_by_index():
    """The j-th pooled coverage is the mean of every draw's j-th; the range its central 90 %."""
    a = np.array([[0.0, 1.0, 0.5, 0.5]])
    b = np.array([[1.0, 1.0, 0.5, 0.0]])
    lo, hi = right_range([a, b])
    pooled = np.array([0.5, 1.0, 0.5, 0.25])
    assert lo[0] == pytest.approx(np.quantile(pooled, 0.05))
    assert hi[0] == pytest.approx(np.quantile(pooled, 0.95))


def test_the_gaussian_read_back_has_the_rounded_counts_standard_deviation():
    """The board Monte Carlo's ``--read-back gaussian``: the same error for the same posture,
    its standard deviation per joint the rounded counts' (1000 postures: within 10 %), and no
    longer on the count grid."""
    import dataclasses

    from selfcal.benchmarks.board.accuracy import GaussianReadBack
    from selfcal.robot.encoder import EncoderSpec

    enc = load_robot("er4u-paper").encoder
    assert enc is not None
    g = GaussianReadBack(**{f.name: getattr(enc, f.name) for f in dataclasses.fields(EncoderSpec)})
    rng = np.random.default_rng(5)
    q = rng.uniform(-1.0, 1.0, (1000, 5))
    e = np.array([g.read_back(x) for x in q]) - q
    assert np.array_equal(g.read_back(q[0]), g.read_back(q[0].copy()))
    assert np.std(e, axis=0) == pytest.approx(enc.read_back_sigma, rel=0.1)
    assert not np.allclose(g.read_back(q[0]), enc.read_back(q[0]))
