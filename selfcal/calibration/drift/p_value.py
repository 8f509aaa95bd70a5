"""A drift check's p-values: the omnibus and directed tests combined, the power a test that
knew the change would have, and the p-value as the verdict line prints it."""

from __future__ import annotations

import numpy as np
from scipy.special import chdtrc, chdtri
from scipy.stats import chi2, ncx2, norm

from selfcal.solver.covariance import psd_sqrt

__all__ = [
    "MIN_P_DRAWS",
    "P_FLOOR",
    "P_TOP",
    "SIZE_DRAWS",
    "chi2_isf",
    "chi2_sf",
    "combined_p",
    "known_change_power",
    "known_size_power",
    "min_p",
    "p_text",
    "smallest_p",
]

P_FLOOR = 1e-15
"""Below this a chi-square tail is rounding (and 0.0 where it underflows): printed as a bound."""


def chi2_sf(x: float, dof: float) -> float:
    """``P(chi2_dof >= x)``: ``scipy.stats.chi2.sf``'s own formula, ``chdtrc(dof, x)``, and its
    answers at the edges (1 where ``x <= 0``, NaN where ``dof <= 0``): the same numbers without
    its generic argument handling, 10 against 140 us a call (under load), which the drift check
    makes for every test of every check (tens of thousands in its Monte Carlo tests)."""
    if not dof > 0:
        return np.float64(np.nan)
    return chdtrc(dof, np.maximum(x, 0.0))


def chi2_isf(p: float, dof: float) -> float:
    """The ``x`` with ``P(chi2_dof >= x) = p`` (``p`` in [0, 1]): ``scipy.stats.chi2.isf``'s own
    formula, ``chdtri(dof, p)``, NaN where ``dof <= 0`` as it gives: the same numbers without
    its generic argument handling (:func:`chi2_sf`)."""
    if not dof > 0:
        return np.float64(np.nan)
    return chdtri(dof, p)


P_TOP = 0.99
"""Above this a p-value is printed as a bound (two significant digits round 0.995 up to "1")."""


def p_text(p: float, smallest: float | None = None, tests: int = 0) -> str:
    """``"p = 0.0023"``, ``"p < 1e-15"`` below :data:`P_FLOOR` (a tail that underflowed to 0
    read as "p = 0", an impossible certainty) and ``"p > 0.99"`` above :data:`P_TOP` (two
    digits printed 0.995 - 1 as "p = 1"). With ``smallest`` (the smallest of the combined
    ``tests``' own p-values, :func:`smallest_p`), a Bonferroni combination above
    :data:`P_TOP` says so and gives it (clipped at 1 or not): the p-value of the combined test
    lies between that and the bound (a new user's unchanged simulated check printed "p = 1"
    where its 11 tests' smallest was 0.24, and a bound of 0.995 "p > 0.99" where one test's
    was 0.09)."""
    if p < P_FLOOR:
        return f"p < {P_FLOOR:g}"
    if smallest is not None and p > P_TOP and smallest <= P_TOP:
        if p >= 1.0:
            return (f"p = 1 as Bonferroni's bound clipped: {tests} tests times their smallest "
                    f"p, {smallest:.2g}")  # fmt: skip
        return (f"p > {P_TOP:g} (Bonferroni's bound: {tests} tests times their smallest p, "
                f"{smallest:.2g})")  # fmt: skip
    return f"p > {P_TOP:g}" if p > P_TOP else f"p = {p:.2g}"


def smallest_p(T: float, dof: int, directed: dict[str, tuple[float, int]]) -> tuple[float, int]:
    """``(smallest, count)``: the smallest of the p-values of the tests :func:`combined_p`
    combines (the omnibus and the directed tests of rank > 0) and their count."""
    tests = [chi2_sf(T, dof)] + [chi2_sf(d, k) for d, k in directed.values() if k > 0]
    return float(min(tests)), len(tests)


def combined_p(T: float, dof: int, directed: dict[str, tuple[float, int]]) -> float:
    """The p-value of "unchanged" from the omnibus statistic ``T`` (chi-square with ``dof``
    degrees of freedom) and the ``directed`` tests (by name how much a change's fit lowers
    ``T`` and its rank, chi-square with that rank): the smallest of the p-values times their
    count (Bonferroni; directed tests of rank 0 are left out), at most 1. Below ``alpha`` in at
    most ``alpha`` of the checks of an unchanged robot whose residuals have the assumed
    covariance, whatever the tests' correlation."""
    smallest, count = smallest_p(T, dof, directed)
    return float(min(1.0, count * smallest))


def known_change_power(noncentrality: float | np.ndarray, alpha: float,
                       dof: int = 1) -> float | np.ndarray:  # fmt: skip
    """The power at level ``alpha`` of a test that knew the change it looks for: ``dof`` = 1 its
    direction and sign (the one-sided normal test of the residuals' projection on the change's
    pixels, the most powerful test of all: Neyman-Pearson), ``dof`` > 1 only the span of
    ``dof`` parameters it lies in (the chi-square of their fit); ``noncentrality`` =
    ``mu^T Sigma^-1 mu`` of the change's pixels ``mu`` under the check's covariance
    ``Sigma``."""
    lam2 = np.asarray(noncentrality, float)
    if dof == 1:
        return norm.sf(norm.isf(alpha) - np.sqrt(lam2))
    return ncx2.sf(chi2.isf(alpha, dof), dof, lam2)


SIZE_DRAWS = 20_000
"""Null draws of :func:`known_size_power` (its critical value; the power from a tenth as
many draws under the change, 2000: a binomial standard error of 0.0049 per check at a power of
0.95, 0.0073 at 0.88, ``sqrt(p (1 - p) / 2000)``)."""
SIZE_DIRECTIONS = 400
"""Directions (a Fibonacci lattice of the sphere) averaging :func:`known_size_power`'s
likelihood ratio."""


def _sphere(k: int) -> np.ndarray:
    """(k, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z**2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def known_size_power(information: np.ndarray, change: np.ndarray, alpha: float, *,
                     draws: int = SIZE_DRAWS, seed: int = 0) -> float:  # fmt: skip
    """The power at level ``alpha`` against ``change`` (3,) of the most powerful test of a
    change of its size in a direction it is not told (uniform over the sphere of 3 parameters:
    e.g. a mount's translation, m), whose whitened pixels' information is ``information`` (3, 3)
    ``G^T Sigma^-1 G`` (``G`` the pixels' derivative by the 3 parameters, ``Sigma`` the check's
    covariance). Its statistic is the likelihood ratio averaged over the sphere's directions
    (Neyman-Pearson against that mixture: no test has a larger power averaged over the
    directions), a function of ``y = G^T Sigma^-1 r``, ``N(0, F)`` under "unchanged" and
    ``N(F x, F)`` with the change ``x``; its critical value and power from ``draws`` and
    ``draws // 10`` draws (``seed``: the same inputs give the same figure). Between the power
    of the chi-square of the 3 parameters (:func:`known_change_power` with ``dof`` 3), which
    knows less, and of the test told the direction (``dof`` 1), which knows more; the mean
    over changes drawn in uniformly random directions is the largest mean power any test of
    the change's kind and size can have."""
    F = np.asarray(information, float)
    x = np.asarray(change, float)
    size = float(np.linalg.norm(x))
    root = psd_sqrt(F)
    U = size * _sphere(SIZE_DIRECTIONS)
    half = 0.5 * np.einsum("ki,ij,kj->k", U, F, U)

    def log_ratio(y: np.ndarray) -> np.ndarray:
        a = y @ U.T - half
        top = a.max(axis=1, keepdims=True)
        return top[:, 0] + np.log(np.mean(np.exp(a - top), axis=1))

    rng = np.random.default_rng(seed)
    crit = np.quantile(log_ratio(rng.standard_normal((draws, 3)) @ root), 1.0 - alpha)
    alt = rng.standard_normal((max(draws // 10, 1), 3)) @ root + F @ x
    return float(np.mean(log_ratio(alt) > crit))


MIN_P_DRAWS = 20_000
"""Null draws of :func:`min_p`: its p-value's Monte Carlo error is about 0.0007 at 0.01."""


def min_p(T: float, dof: int, directed: dict[str, tuple[float, int]],
          columns: dict[str, np.ndarray], *, draws: int = MIN_P_DRAWS) -> float:  # fmt: skip
    """The p-value of "unchanged" from the same tests as :func:`combined_p`, without its
    Bonferroni price: the probability under "unchanged" that the smallest of the tests'
    p-values is at most the one seen, from the tests' joint distribution rather than the
    count. ``T`` the omnibus statistic (the whitened residuals' squared norm, chi-square with
    ``dof``), ``directed`` by name how much a change's fit lowers ``T`` and its rank,
    ``columns`` by the same name that change's whitened columns (2k, c) (the fit's design).

    Under "unchanged" the whitened residuals are ``z ~ N(0, I)``; every test is a function of
    ``z``'s part in the span of all the columns together (``r_u`` coordinates: each directed
    test the squared norm of its projection) and of the squared norm of the rest (chi-square
    with ``dof - r_u``), so ``draws`` draws of those (a fixed seed: the same residuals give the
    same verdict) give the smallest p-value's distribution. The result lies between the
    smallest p-value and :func:`combined_p` (Bonferroni's bound); below what the draws resolve
    it is :func:`combined_p`."""
    keys = [k for k, (_, rank) in directed.items() if rank > 0]
    p_seen = [chi2_sf(T, dof)] + [chi2_sf(directed[k][0], directed[k][1]) for k in keys]
    smallest, bonferroni = float(min(p_seen)), combined_p(T, dof, directed)
    if not keys:
        return bonferroni
    Q, s, _ = np.linalg.svd(np.concatenate([columns[k] for k in keys], axis=1),
                            full_matrices=False)  # fmt: skip
    Q = Q[:, s > s[0] * 1e-10]
    bases = []  # each test's orthonormal basis in the union's coordinates
    for k in keys:
        U, sk, _ = np.linalg.svd(Q.T @ columns[k], full_matrices=False)
        bases.append(U[:, : directed[k][1]] if sk.size else U[:, :0])
    rng = np.random.default_rng(0)
    z = rng.standard_normal((draws, Q.shape[1]))
    rest = rng.chisquare(dof - Q.shape[1], draws) if dof > Q.shape[1] else np.zeros(draws)
    # a draw's smallest p-value is at most the one seen when a statistic reaches its test's
    # quantile at that level
    hit = np.sum(z**2, axis=1) + rest >= chi2_isf(smallest, dof)
    for U in bases:
        hit |= np.sum((z @ U) ** 2, axis=1) >= chi2_isf(smallest, U.shape[1])
    hits = int(np.sum(hit))
    return float(np.clip((1 + hits) / (1 + draws), smallest, bonferroni))
