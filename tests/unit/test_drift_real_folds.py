"""The real drift benchmark's joint estimate (selfcal/benchmarks/drift/real_folds.py): the held
deviation's share ``c`` and the per-view misfit's scale ``a`` from the folds' residual energy in
the deviation's pixel span and outside it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.benchmarks.drift.real_folds import (
    Fold,
    excess_without,
    joint_moments,
    ratios,
    sandwich_excess,
    shared_check,
    shared_twist,
)
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


def test_the_shared_twist_is_found_and_a_shared_error_of_its_size_accepts_it():
    """A fold whose views' residuals hold one world twist ``x`` shared by them (the check's
    covariance knows nothing of it): the fit finds ``x`` within 3 of its standard deviations,
    the check as it is says changed, and with ``x``'s size as the shared error's covariance it
    does not."""
    rng = np.random.default_rng(3)
    (fold,) = _folds(0.0, 1.0, 1, rng)
    x = np.array([3.0, -2.0, 1.0, 0.5, 1.5, -1.0])
    views = []
    for v in fold.views:
        W = rng.normal(size=(12, 6))
        views.append(dataclasses.replace(v, world=W, r=v.r + W @ x))
    fold = dataclasses.replace(fold, views=views)
    fit, P = shared_twist(fold, 0.0)
    assert np.all(np.abs(fit - x) < 3 * np.sqrt(np.diag(P))), (fit, x)
    assert shared_check(fold, 0.0, np.zeros((6, 6)), eye_to_hand=False).changed
    assert not shared_check(fold, 0.0, np.diag(x**2), eye_to_hand=False).changed


def test_the_sandwich_excess_is_what_the_per_view_misfit_adds_to_the_estimate_spread():
    """Pixels drawn with a per-view misfit (each view's ``local`` beyond the white ``s2``): the
    least-squares estimate of the fitted columns spreads as ``s2 (H^T H)^-1`` plus the excess,
    within 3 standard errors of 4000 draws per diagonal entry (the white part alone is far too
    small); the held column gets none."""
    rng = np.random.default_rng(11)
    s2, views = 0.04, []
    for _ in range(4):
        A = rng.normal(size=(12, 6))
        local = s2 * np.eye(12) + A @ np.diag(rng.uniform(0.05, 0.2, 6)) @ A.T
        z = np.zeros((12, 6))
        views.append(ViewJacobians(np.zeros(12), local, rng.normal(size=(12, 3)),
                                   rng.normal(size=(12, 2)), z, z, z, np.eye(6), np.eye(6),
                                   np.zeros((6, 3))))  # fmt: skip
    fitted = np.array([True, False, True, True, True])
    E = sandwich_excess(views, fitted, s2)
    H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in views])[:, fitted]
    L = np.linalg.cholesky(np.block([[v.local if i == j else np.zeros((12, 12))
                                      for j in range(4)] for i, v in enumerate(views)]))  # fmt: skip
    x = np.linalg.lstsq(H, L @ rng.normal(size=(48, 4000)), rcond=None)[0]
    white = s2 * np.linalg.inv(H.T @ H)
    var = np.mean(x**2, axis=1)
    want = np.diag(white) + np.diag(E)[fitted]
    assert np.all(np.abs(var - want) < 3 * want * np.sqrt(2 / 4000)), (var, want)
    assert np.all(var > 2 * np.diag(white)), (var, np.diag(white))
    assert not E[1].any() and not E[:, 1].any()


def test_a_folds_own_miss_does_not_size_the_error_that_excuses_it():
    """Five folds of 4 held-out frames whose flange errors are what their estimation error
    explains (|e|^2 = tr S = 3e-6 m^2, no noise), but fold 3 misses by 2 mm per coordinate
    more (|e|^2 = 15e-6): pooled over all folds (in sample) the excess is sqrt(2.4e-6 / 3) =
    0.894 mm (z = 4.4 > 2); without fold 3's own frames it is 0 (its check is not excused by
    its own miss), and another fold's out-of-sample figure still holds fold 3's miss:
    sqrt(3e-6 / 3) = 1 mm. The orientation, with no excess, is 0 throughout."""
    rng = np.random.default_rng(2)

    def tool(e2: float, fold: int) -> dict[str, np.ndarray]:
        u = rng.normal(size=(4, 3))
        e = np.zeros((4, 6))
        e[:, :3] = np.sqrt(e2) * u / np.linalg.norm(u, axis=1, keepdims=True)
        e[:, 3:] = 1e-3 / np.sqrt(3.0)  # |w|^2 = 1e-6 rad^2 = tr S's orientation part
        S = np.tile(np.diag([1e-6] * 3 + [1e-6 / 3] * 3), (4, 1, 1))
        # each frame's estimation error its own (6 parameters of 120, S = G C G^T, no
        # information shared between the folds' fits): the rows independent
        G = np.zeros((4, 6, 120))
        for r in range(4):
            G[r, :, 6 * (4 * fold + r) : 6 * (4 * fold + r + 1)] = np.sqrt(S[r])
        C, A = np.tile(np.eye(120), (4, 1, 1)), np.zeros((4, 120, 120))
        return {"frame": np.arange(4), "e": e, "S": S, "N": np.zeros((4, 6, 6)), "G": G,
                "C": C, "A": A}  # fmt: skip

    base = _folds(0.0, 1.0, 1, rng)[0]
    folds = [dataclasses.replace(base, tool=tool(15e-6 if i == 2 else 3e-6, i)) for i in range(5)]
    pos, rot = excess_without(folds, None)
    assert pos == pytest.approx(np.sqrt(2.4e-6 / 3.0)) and rot == 0.0
    assert excess_without(folds, 2) == (0.0, 0.0)
    assert excess_without(folds, 0)[0] == pytest.approx(1e-3)
    # without the flange errors (not computed) there is nothing to size it from
    assert excess_without([base] * 3, None) == (0.0, 0.0)
