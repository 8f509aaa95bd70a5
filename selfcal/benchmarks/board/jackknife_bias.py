"""Benchmark: how far the board route's jackknife over its folds over-states the variance of
a least-squares estimate (issue #29; :mod:`selfcal.calibration.board.spread`).

The delete-a-fold jackknife variance ``(k - 1) / k * sum_i |t_i - t_mean|^2`` is biased upward
for an estimator whose folds carry unequal shares of the information (Efron and Stein's
inequality): the fewer the configurations per parameter, the more. A synthetic check, no
calibration: a linear model of ``p`` parameters, ``rows`` unit-noise rows per configuration
(Gaussian design), the configurations dealt into folds by the board's own rule
(:func:`selfcal.calibration.board.folds.fold_labels`), a 3-vector predicted from the estimate
(a tool point). For a linear estimate the jackknife's expectation is exact:
``t_i = L_i y`` gives ``E[jk] = (k - 1) / k * sum_i ||L_i - L_mean||_F^2`` against the true
variance ``||L||_F^2`` of the fit on every row. Printed: that ratio's mean and range over
``--designs`` random designs per case (seeded), 1 meaning no bias.

Run: ``uv run python -m selfcal.benchmarks.board.jackknife_bias [--designs 200] [--seed 0]``
(a second at most).
"""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.folds import fold_labels

CASES = ((15, 2, 1), (15, 2, 4), (15, 2, 8), (15, 10, 4), (60, 2, 4), (5, 10, 4))
"""(configurations, rows per configuration, parameters) of each case."""


def expected_ratio(X: np.ndarray, fold: np.ndarray, x0: np.ndarray) -> float:
    """The jackknife's expected variance over the true one for the least-squares fit of the
    rows ``X`` (m, p) (unit noise) predicting ``x0`` (3, p) @ estimate, the rows dealt into the
    folds ``fold`` (m,)."""
    L = x0 @ np.linalg.pinv(X)
    folds = np.unique(fold)
    k = len(folds)
    Ls = np.zeros((k, *L.shape))
    for j, f in enumerate(folds):
        keep = fold != f
        Ls[j][:, keep] = x0 @ np.linalg.pinv(X[keep])
    jk = (k - 1) / k * np.sum((Ls - Ls.mean(axis=0)) ** 2)
    return float(jk / np.sum(L**2))


def main(argv: list[str] | None = None) -> None:
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print("| configurations | rows each | parameters | folds | E[jackknife] / true: mean (range) |")
    print("|---|---|---|---|---|")
    for n_cfg, rows, p in CASES:
        fold = fold_labels(np.repeat(np.arange(n_cfg), rows))
        r = [expected_ratio(rng.normal(size=(n_cfg * rows, p)), fold, rng.normal(size=(3, p)))
             for _ in range(args.designs)]  # fmt: skip
        k = len(np.unique(fold))
        print(f"| {n_cfg} | {rows} | {p} | {k} | {np.mean(r):.2f} ({min(r):.2f}-{max(r):.2f}) |")


if __name__ == "__main__":
    main()
