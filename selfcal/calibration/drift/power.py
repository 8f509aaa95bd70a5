"""What a drift check of these views can find: its own power against a move of the mount (issue
#29).

The check (:func:`selfcal.calibration.drift.images.image_drift_check`) says "changed" when the
smallest p-value of its tests (the omnibus and each candidate change's directed test,
:mod:`selfcal.calibration.drift.attribution`) times their count is below ``alpha``. Every test
is a function of the whitened residuals ``rw``; under a move ``x`` (m) of the chain's tool
mount without turning (eye-in-hand the camera on the flange, eye-to-hand the board on it) they
are ``N(Gw x, I)``, ``Gw`` the whitened pixels of the mount's translation. So the check's power
against a move of a given size in a random direction (uniform over the sphere) is a property of
the views and the check's covariance alone, known before any change. :func:`check_power` draws
it from the candidates' scores ``b = Gw_all^T rw ~ N(K x, K)`` (``K = Gw_all^T Gw_all``, the Gram
matrix of every candidate's whitened columns): each directed statistic is ``b_k^T K_kk^+ b_k``,
the omnibus ``b^T K^+ b`` plus a chi-square of the degrees of freedom no candidate reaches:
the check's own statistics, linearised. Not drawn: the outlier step, the views' own noise and
the folds' second null (:func:`~selfcal.calibration.drift.images.fold_recheck`); where the
calibration's frames showed a per-view misfit the second null runs and "changed" needs both
tests, so the figure is then an upper one (:attr:`ShiftPower.upper`).

How many images like these would reach :data:`TARGET_POWER` (:func:`shift_power`): ``r`` times
the views' information with the calibration's estimate shared among them (Woodbury:
``K_r = r A - r^2 B C (I + r E C)^-1 B^T``, ``A = G^T D^-1 G``, ``B = G^T D^-1 H``,
``E = H^T D^-1 H``, ``D`` the views' own covariance, ``H`` the pixels' derivative by the
estimated parameters, ``C`` their covariance; ``r = 1`` is ``K``), i.e. more images at postures
spread as these, each with its own noise and joint read-back. Not given where views are paired
with the calibration's frames (their estimate's error cancels: another covariance).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.stats import chi2

from selfcal.calibration.drift.attribution import candidate_fits
from selfcal.calibration.drift.covariance import view_covariance
from selfcal.calibration.drift.views import ViewJacobians
from selfcal.solver.covariance import psd_sqrt

__all__ = [
    "MOST_IMAGES",
    "MOUNT_TEST",
    "POWER_DRAWS",
    "SHIFT_MM",
    "TARGET_POWER",
    "ShiftPower",
    "check_power",
    "shift_power",
]

SHIFT_MM = 0.2
"""The move of the mount whose power the check states (mm; issue #29's target: found with 5
images at :data:`TARGET_POWER`)."""
TARGET_POWER = 0.95
"""The power for which the check says how many images like the given ones would reach it."""
POWER_DRAWS = 4000
"""Draws of :func:`check_power` (a fixed seed; a binomial standard error of 0.0035 at a power
of 0.95, 0.0063 at 0.8)."""
MOST_IMAGES = 100
"""The most images :func:`shift_power` considers for :data:`TARGET_POWER`."""
MOUNT_TEST = "hand-eye translation"
"""The check's directed test of the mount's translation (:func:`selfcal.calibration.drift.
attribution.candidate_fits`)."""


@dataclass(frozen=True)
class ShiftPower:
    """The check's power (:func:`shift_power`) against a move of the mount by ``size_mm``
    without turning, in a random direction: ``power`` with these ``images``;
    ``images_for_target`` about how many images like these reach :data:`TARGET_POWER` (None:
    more than :data:`MOST_IMAGES`, or views paired with the calibration's frames); ``upper``:
    the folds' second null runs on this calibration, so the check finds at most that;
    ``mount``: what the mount holds on the flange (eye-in-hand the camera, eye-to-hand the
    board)."""

    size_mm: float
    power: float
    images: int
    images_for_target: int | None
    upper: bool = False
    mount: str = "camera"

    def line(self) -> str:
        """The power in one line."""
        how = "at most " if self.upper else ""
        out = (f"power: {self.images} image(s) like these find a {self.size_mm:g} mm move of "
               f"the {self.mount}'s mount on the flange (a random direction, not turned) "
               f"in {how}{self.power:.0%} of checks")  # fmt: skip
        if self.power >= TARGET_POWER:
            return out
        if self.images_for_target is None:
            return out + f"; not even {MOST_IMAGES} images like these find it in {TARGET_POWER:.0%}"
        return (out + f"; take about {self.images_for_target} images like these to find it in "
                f"{TARGET_POWER:.0%}")  # fmt: skip

    def to_json(self) -> dict:
        """The power as JSON."""
        return {"size_mm": self.size_mm, "power": self.power, "images": self.images,
                "target_power": TARGET_POWER, "images_for_target": self.images_for_target,
                "upper_bound": self.upper, "mount": self.mount}  # fmt: skip


def check_power(K: np.ndarray, tests: dict[str, tuple[slice, int]], dof: float, shift: slice,
                size: float, alpha: float, *, draws: int = POWER_DRAWS,
                seed: int = 0) -> float:  # fmt: skip
    """The share of ``draws`` checks (module docstring) that say "changed" at ``alpha``
    (Bonferroni over the omnibus and the ``tests``, by name their columns of ``K`` and rank)
    against a change of ``size`` (the columns' unit, e.g. m) in a random direction of the
    columns ``shift``; ``K`` the candidates' whitened Gram matrix, ``dof`` the omnibus's degrees
    of freedom."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((draws, shift.stop - shift.start))
    u *= size / np.linalg.norm(u, axis=1, keepdims=True)
    b = u @ K[shift, :] + rng.standard_normal((draws, len(K))) @ psd_sqrt(K)
    rank = np.linalg.matrix_rank(K, hermitian=True)
    T = np.einsum("di,ij,dj->d", b, np.linalg.pinv(K, hermitian=True), b)
    T = T + (rng.chisquare(dof - rank, draws) if dof > rank else 0.0)
    p = chi2.sf(T, dof)
    for cols, k in tests.values():
        Kk = np.linalg.pinv(K[cols, cols], hermitian=True)
        p = np.minimum(p, chi2.sf(np.einsum("di,ij,dj->d", b[:, cols], Kk, b[:, cols]), k))
    return float(np.mean(np.minimum(1.0, (1 + len(tests)) * p) < alpha))


def _columns(views: list[ViewJacobians], L: np.ndarray,
             eye_to_hand: bool) -> tuple[np.ndarray, dict[str, tuple[slice, int]], np.ndarray]:  # fmt: skip
    """Every directed test's columns whitened by ``L`` (the Cholesky factor of a covariance of
    the stacked ``views``), side by side, the tests by name (their columns and rank) and the
    estimated parameters' derivative ``H`` whitened the same way."""

    def white(M: np.ndarray) -> np.ndarray:
        return solve_triangular(L, M, lower=True)

    fits = candidate_fits(white, np.zeros(len(L)), views, eye_to_hand=eye_to_hand)
    at, tests = 0, {}
    for key, G in fits.directed_columns.items():
        tests[key] = (slice(at, at + G.shape[1]), fits.directed[key][1])
        at += G.shape[1]
    Gw = np.concatenate(list(fits.directed_columns.values()), axis=1)
    H = white(np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in views]))
    return Gw, tests, H


def shift_power(C: np.ndarray, views: list[ViewJacobians], *, eye_to_hand: bool, alpha: float,
                C_noise: np.ndarray | None = None, size_mm: float = SHIFT_MM,
                upper: bool = False, draws: int = POWER_DRAWS,
                search: bool = True) -> ShiftPower:  # fmt: skip
    """The check's power against a move of the chain's tool mount by ``size_mm`` without turning
    (module docstring; ``C``, ``C_noise``, ``alpha``, ``eye_to_hand`` as the check's, ``upper``
    whether its folds' second null runs) and, with ``search``, how many images like these reach
    :data:`TARGET_POWER`."""
    dof = sum(len(v.r) for v in views)
    Gw, tests, _ = _columns(views, np.linalg.cholesky(view_covariance(C, views, C_noise)),
                            eye_to_hand)  # fmt: skip
    tests = {k: t for k, t in tests.items() if t[1] > 0}
    mount, size, n = tests[MOUNT_TEST][0], size_mm * 1e-3, len(views)
    power = check_power(Gw.T @ Gw, tests, dof, mount, size, alpha, draws=draws)
    need: int | None = None
    if power >= TARGET_POWER:
        need = n
    elif search and not any(v.paired for v in views):
        gram = _replicated(C, views, eye_to_hand)

        def reaches(m: int) -> bool:
            got = check_power(gram(m / n), tests, dof * m / n, mount, size, alpha, draws=draws)
            return got >= TARGET_POWER

        lo, hi = n, min(2 * n, MOST_IMAGES)  # lo does not reach it; does hi?
        found = hi > lo and reaches(hi)
        while not found and hi < MOST_IMAGES:
            lo, hi = hi, min(2 * hi, MOST_IMAGES)
            found = reaches(hi)
        while found and hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if reaches(mid) else (mid, hi)
        need = hi if found else None
    return ShiftPower(size_mm, power, n, need, upper, "board" if eye_to_hand else "camera")


def _replicated(C: np.ndarray, views: list[ViewJacobians],
                eye_to_hand: bool) -> Callable[[float], np.ndarray]:  # fmt: skip
    """``r -> K_r`` (module docstring): the candidates' whitened Gram matrix of ``r`` times the
    ``views``' images (unpaired) with the calibration's estimate (``C``) shared among them."""
    L = np.linalg.cholesky(view_covariance(np.zeros_like(C), views))  # D, the views' own
    G, _, H = _columns(views, L, eye_to_hand)
    A, B, E = G.T @ G, G.T @ H, H.T @ H
    C = np.asarray(C, float)
    return lambda r: r * A - r**2 * B @ C @ np.linalg.solve(np.eye(len(C)) + r * E @ C, B.T)
