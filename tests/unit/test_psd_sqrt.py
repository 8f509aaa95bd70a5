"""The symmetric square root of a covariance (selfcal/solver/covariance.py ``psd_sqrt``): a
function of the matrix alone, not of the eigenvectors' signs, order or basis in a repeated
eigenvalue's space that the decomposition returns (issue #30: the plan's forecast draws flipped
with round-off when they went through ``V diag(sqrt(w))``), and its draws have the covariance."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from selfcal.errors import UsageError
from selfcal.solver.covariance import psd_sqrt


def _spectrum(seed: int, p: int, rank: int, repeat: int) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (p,) (``p - rank`` zeros, the first ``repeat`` of the others equal) and
    orthonormal eigenvectors (p, p) of a random covariance."""
    rng = np.random.default_rng(seed)
    w = np.zeros(p)
    w[:rank] = np.exp(rng.uniform(-6.0, 3.0, rank))
    w[:repeat] = w[0]
    V = np.linalg.qr(rng.standard_normal((p, p)))[0]
    return w, V


@settings(max_examples=examples(60), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 9), data=st.data())
def test_the_root_is_the_same_whatever_eigenvectors_the_decomposition_returns(seed, p, data):
    rank = data.draw(st.integers(0, p))
    repeat = data.draw(st.integers(0, rank))
    w, V = _spectrum(seed, p, rank, repeat)
    C = (V * w) @ V.T
    rng = np.random.default_rng(seed + 1)
    # another valid decomposition of C: a rotation inside the repeated eigenvalue's space and
    # inside the null space, every column's sign flipped at random, the columns permuted
    W = V.copy()
    for cols in (np.arange(repeat), np.arange(rank, p)):
        if len(cols) > 1:
            W[:, cols] = W[:, cols] @ np.linalg.qr(rng.standard_normal((len(cols),) * 2))[0]
    W = W * rng.choice([-1.0, 1.0], p)
    order = rng.permutation(p)
    expected = (V * np.sqrt(w)) @ V.T

    def eigh(M):  # what LAPACK may as well have returned for C
        assert np.allclose(M, C, rtol=0.0, atol=1e-12 * max(w.max(initial=0.0), 1e-300))
        return w[order], W[:, order]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(np.linalg, "eigh", eigh)
        S = psd_sqrt(C)
    scale = np.sqrt(w.max(initial=0.0)) or 1.0
    assert np.allclose(S, expected, rtol=0.0, atol=1e-12 * scale)
    assert np.allclose(S, S.T, rtol=0.0, atol=0.0)
    assert np.allclose(S @ S, C, rtol=0.0, atol=1e-12 * scale**2)


def test_draws_through_the_root_have_the_covariance():
    w, V = _spectrum(7, 6, 5, 2)  # rank 5, a repeated eigenvalue
    C = (V * w) @ V.T
    n = 40_000
    x = np.random.default_rng(3).standard_normal((n, 6)) @ psd_sqrt(C).T
    C_hat = x.T @ x / n
    d = np.sqrt(np.diag(C))
    se = np.sqrt((np.outer(d, d) ** 2 + C**2) / n)  # a sample covariance's standard error
    z = np.abs(C_hat - C)[se > 0] / se[se > 0]
    assert z.max() < 4.0  # 21 entries; this seed reaches 1.8 (a normal's 4 sigma: 6e-5 each)
    # nothing off C's span (a zero eigenvalue that round-off leaves at ~1e-16 of the largest has a
    # root ~1e-8 of its root: this seed's draws reach 4.7e-8)
    assert np.abs(x @ V[:, 5]).max() < 1.5e-7 * np.sqrt(w.max())


def test_round_off_in_the_matrix_moves_the_root_by_round_off():
    w, V = _spectrum(11, 8, 8, 3)
    C = (V * w) @ V.T
    E = np.random.default_rng(5).standard_normal((8, 8))
    C2 = C + 1e-12 * np.abs(C).max() * (E + E.T)  # calibration.json's 12th digit
    dS = np.abs(psd_sqrt(C2) - psd_sqrt(C)).max() / np.abs(psd_sqrt(C)).max()
    assert dS < 2e-10  # full rank: Lipschitz, ~cond * 1e-12 (this draw: 5.8e-11)


@settings(max_examples=examples(60), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), p=st.integers(1, 9), data=st.data())
def test_a_rank_deficient_matrix_has_a_root_that_squares_back_to_it(seed, p, data):
    """LAPACK's own decomposition (nothing replaced) of a C with ``p - rank`` zero eigenvalues:
    round-off leaves them at ~1e-16 of the largest, either sign; the root still squares back
    to C and stays (nearly) off C's null space."""
    rank = data.draw(st.integers(0, p - 1))
    repeat = data.draw(st.integers(0, rank))
    w, V = _spectrum(seed, p, rank, repeat)
    C = (V * w) @ V.T
    S = psd_sqrt(C)
    scale = w.max(initial=0.0) or 1.0
    assert np.array_equal(S, S.T)
    # 3000 such draws reach 3.7e-15 of the largest eigenvalue
    assert np.abs(S @ S - C).max() < 1e-14 * scale
    # a null direction's root: the square root of round-off (3000 draws: 2.1e-8 of the root)
    assert np.abs(S @ V[:, rank:]).max() < 6e-8 * np.sqrt(scale)


def test_round_off_in_a_rank_deficient_matrix_moves_the_root_by_its_square_root():
    """Not Lipschitz at a zero eigenvalue: a relative change e of C moves the root by up to
    ~sqrt(e) (psd_sqrt's docstring: the draws then differ in their 6th digit, not their last)."""
    w, V = _spectrum(4, 8, 6, 0)  # rank 6 of 8
    C = (V * w) @ V.T
    E = np.random.default_rng(4).standard_normal((8, 8))
    dS = []
    for e in (1e-12, 1e-14):
        C2 = C + e * np.abs(C).max() * (E + E.T)
        dS.append(np.abs(psd_sqrt(C2) - psd_sqrt(C)).max() / np.abs(psd_sqrt(C)).max())
    # this draw: 4.5e-7 (full rank: below 2e-10, the test above; other draws reach 1.6e-6)
    assert 1.5e-7 < dS[0] < 1.5e-6
    assert 5.0 < dS[0] / dS[1] < 20.0  # 100 times smaller a change, 12 times smaller a move


@pytest.mark.parametrize("bad", [np.ones((2, 3)), np.ones(3), np.array([[1.0, np.nan], [0, 1]])])
def test_a_matrix_that_is_not_square_and_finite_is_refused(bad):
    with pytest.raises(UsageError, match="finite square matrix"):
        psd_sqrt(bad)
