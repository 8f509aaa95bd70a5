"""The real drift benchmark's joint estimate (selfcal/benchmarks/drift_real_folds.py): the held
deviation's share ``c`` and the per-view misfit's scale ``a`` from the folds' residual energy in
the deviation's pixel span and outside it."""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.drift_real_folds import Fold, joint_moments, ratios
from selfcal.calibration.drift.views import ViewJacobians


def _folds(c: float, a: float, count: int, rng: np.random.Generator) -> list[Fold]:
    """``count`` folds of 3 views of 12 pixels each, 5 parameters whose deviation part ``V`` is
    of rank 2, residuals drawn from the covariance at ``(c, a)``."""
    out = []
    for _ in range(count):
        H = rng.normal(size=(36, 5))
        C0 = np.diag(rng.uniform(0.01, 0.02, 5))
        B = rng.normal(size=(5, 2))
        V = B @ B.T
        views, misfit, S = [], [], H @ (C0 + c * V) @ H.T
        for i in range(3):
            A = rng.normal(size=(12, 6))
            M = A @ np.diag(rng.uniform(0.1, 0.3, 6)) @ A.T / 6
            local = 0.05 * np.eye(12)
            S[12 * i : 12 * i + 12, 12 * i : 12 * i + 12] += local + a * M
            misfit.append(M)
            views.append((H[12 * i : 12 * i + 12], local))
        r = np.linalg.cholesky(S) @ rng.normal(size=36)
        z = np.zeros((12, 6))
        vjs = [ViewJacobians(r[12 * i : 12 * i + 12], L, Hi[:, :3], Hi[:, 3:], z, z, z,
                             np.eye(6), np.eye(6), np.zeros((6, 3)))
               for i, (Hi, L) in enumerate(views)]  # fmt: skip
        out.append(Fold(vjs, misfit, C0, V))
    return out


def test_the_joint_estimate_finds_the_share_and_the_misfit_it_was_drawn_with():
    """400 folds drawn at c = 0.3, a = 0.6 give them back within 3 standard errors (the
    estimate's spread over 200 draws of 100 folds is 0.040 in c and 0.039 in a, so about 0.02
    at 400; its mean over them 0.301 / 0.599: no bias); the pooled prediction at the estimate
    matches the residuals' energy (the two moments sum to it)."""
    folds = _folds(0.3, 0.6, 400, np.random.default_rng(5))
    c, a = joint_moments(folds, 1e-6)
    assert abs(c - 0.3) < 0.06 and abs(a - 0.6) < 0.06, (c, a)
    assert abs(ratios(folds, c, a)[1] - 1.0) < 1e-9
    # the other way round (the deviation's share read as the misfit) is far off
    assert abs(ratios(folds, a, c)[1] - 1.0) > 0.1
