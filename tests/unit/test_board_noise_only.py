"""One truth, new noise only (selfcal.benchmarks.board.noise_only, issue #29): the read-back
whose count grid moves per draw, and the empirical against the predicted covariance."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.benchmarks.board.noise_only import DitheredReadBack, ratios
from selfcal.robot.definition import load_robot
from selfcal.robot.encoder import EncoderSpec

_ENCODER = load_robot("er4u-paper").encoder


def _dithered(shift: np.ndarray) -> DitheredReadBack:
    assert _ENCODER is not None
    fields = {f.name: getattr(_ENCODER, f.name) for f in dataclasses.fields(EncoderSpec)}
    return DitheredReadBack(**fields, shift=shift)


def test_an_unshifted_grid_reads_back_as_the_controller_does():
    """Shift 0 is the plain rounding of every motor's count (the differential wrist too)."""
    q = np.random.default_rng(3).uniform(-1.0, 1.0, (50, 5))
    d = _dithered(np.zeros(5))
    assert _ENCODER is not None
    assert np.array_equal(d.read_back(q), _ENCODER.read_back(q))


def test_a_shifted_grid_gives_one_posture_the_roundings_error_anew_per_draw():
    """One posture read back with the grid shifted by a new uniform fraction per draw: the
    errors are zero-mean with the table's standard deviation (the wrist's two motors'
    half-difference and half-sum included), and differ between draws."""
    q = np.array([0.3, -0.7, 1.1, 0.2, -0.4])
    rng = np.random.default_rng(11)
    e = np.array([_dithered(rng.uniform(-0.5, 0.5, 5)).read_back(q) - q for _ in range(4000)])
    sigma = _dithered(np.zeros(5)).read_back_sigma
    assert np.std(e, axis=0) == pytest.approx(sigma, rel=0.035)  # 3 sampling sd
    assert np.all(np.abs(e.mean(axis=0)) < 4 * sigma / np.sqrt(len(e)))
    assert len(np.unique(e[:, 0])) > 100


def test_the_ratios_are_the_empirical_variance_along_the_predicted_directions():
    """Errors drawn from diag(9, 4, 1) in a rotated frame, the prediction twice as wide along
    its largest direction: the ratios are 0.5, 1, 1 (largest predicted variance first) to the
    sampling spread, and the predicted variances are returned in that order."""
    rng = np.random.default_rng(2)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    true = Q @ np.diag([9.0, 4.0, 1.0]) @ Q.T
    E = rng.multivariate_normal(np.zeros(3), true, 20000)
    P = Q @ np.diag([18.0, 4.0, 1.0]) @ Q.T
    rat, lam = ratios(E, P)
    assert lam == pytest.approx([18.0, 4.0, 1.0])
    assert rat == pytest.approx([0.5, 1.0, 1.0], rel=0.03)  # 3 sampling sd
