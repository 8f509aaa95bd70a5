"""A drift check's p-values: the omnibus and directed tests combined, the power a test that
knew the change would have, and the p-value as the verdict line prints it."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2, ncx2, norm

__all__ = ["P_FLOOR", "combined_p", "known_change_power", "p_text"]

P_FLOOR = 1e-15
"""Below this a chi-square tail is rounding (and 0.0 where it underflows): printed as a bound."""


def p_text(p: float) -> str:
    """``"p = 0.0023"``, or ``"p < 1e-15"`` below :data:`P_FLOOR` (a tail that underflowed to 0
    read as "p = 0", an impossible certainty)."""
    return f"p < {P_FLOOR:g}" if p < P_FLOOR else f"p = {p:.2g}"


def combined_p(T: float, dof: int, directed: dict[str, tuple[float, int]]) -> float:
    """The p-value of "unchanged" from the omnibus statistic ``T`` (chi-square with ``dof``
    degrees of freedom) and the ``directed`` tests (by name how much a change's fit lowers
    ``T`` and its rank, chi-square with that rank): the smallest of the p-values times their
    count (Bonferroni; directed tests of rank 0 are left out), at most 1. Below ``alpha`` in at
    most ``alpha`` of the checks of an unchanged robot whose residuals have the assumed
    covariance, whatever the tests' correlation."""
    tests = [chi2.sf(T, dof)] + [chi2.sf(d, k) for d, k in directed.values() if k > 0]
    return float(min(1.0, len(tests) * min(tests)))


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
