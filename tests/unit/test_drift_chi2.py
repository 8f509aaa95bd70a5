"""The drift check's chi-square tails (selfcal.calibration.drift.p_value ``chi2_sf``,
``chi2_isf``) are scipy.stats.chi2's numbers, bit for bit, at the edges too: they replace
``chi2.sf`` / ``chi2.isf`` in the check's p-values, where those took most of a check's time."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from selfcal.calibration.drift.p_value import chi2_isf, chi2_sf

EDGES = [-np.inf, -1.0, -1e-12, -0.0, 0.0, 1e-300, 1e-12, 0.5, 3.0, 700.0, 1e4, np.inf, np.nan]
DOFS = [-1, 0, 0.5, 1, 2, 3, 6, 11, 68, 5000]


def _same(a, b) -> bool:
    return type(a) is type(b) and (a == b or (np.isnan(a) and np.isnan(b)))


def test_the_tail_and_its_inverse_are_scipys():
    rng = np.random.default_rng(0)
    xs = [*EDGES, *rng.uniform(0.0, 300.0, 50)]
    ps = [0.0, 1e-300, 1e-15, 0.002, 0.2, 1.0 - 1e-12, 1.0, *rng.uniform(0.0, 1.0, 50)]
    wrong = [("sf", x, k) for k in DOFS for x in xs if not _same(chi2_sf(x, k), chi2.sf(x, k))]
    wrong += [("isf", p, k) for k in DOFS for p in ps if not _same(chi2_isf(p, k), chi2.isf(p, k))]
    assert not wrong, wrong[:10]
    assert chi2_sf(-1.0, 3) == 1.0 and np.isnan(chi2_sf(1.0, 0))  # the edges checked above
