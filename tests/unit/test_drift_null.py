"""The drift check's null distributions on small analytic setups (issue #29, review findings 5
and 6): the folds' excess weighed in each held-out row's own metric, and a paired view's
correlation with the unpaired ones through its frame's noise in the calibration's estimate."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.accuracy import excess, whitened_excess
from selfcal.calibration.drift.fold_error import fold_excess
from selfcal.calibration.drift.images import _covariance, image_drift_check
from selfcal.calibration.drift.views import ViewJacobians


def _anisotropic_rows(m: float, draws: int, rng: np.random.Generator):
    """``draws`` sets of 20 held-out 3-vectors, each row's covariance 0.05^2 across and 1 along
    its own random line of sight (a single view's pose), plus an isotropic excess ``m`` per
    coordinate; with the covariances."""
    R = Rotation.random(20, random_state=4).as_matrix()
    V = R @ np.diag([0.05**2, 0.05**2, 1.0]) @ R.transpose(0, 2, 1)
    L = np.linalg.cholesky(V)
    z = rng.standard_normal((draws, 20, 3))
    return np.einsum("rij,drj->dri", L, z) + m * rng.standard_normal((draws, 20, 3)), V


def test_the_whitened_excess_holds_its_level_and_finds_what_depth_noise_hides():
    """400 draws of 20 anisotropic rows. No excess: the whitened rule counts one in 3 % (its
    two standard errors of a chi-square with 60 dof: 2.3 % for a normal), the squared norms'
    isotropic rule in 10 % (their standard error assumes three equal variances, so the depth's
    spread passes for an excess). An excess of 0.2 per coordinate (4x the rows' across, a
    fifth of their depth): the whitened rule finds it in every draw (median 0.201), the
    squared norms' in 22 % (median 0)."""
    rng = np.random.default_rng(3)
    for m, least, most in ((0.0, 0.0, 0.06), (0.2, 0.95, 1.0)):
        e, V = _anisotropic_rows(m, 400, rng)
        white = np.array([whitened_excess(x, V) for x in e])
        assert least <= np.mean(white > 0) <= most
        if m > 0:
            assert 0.8 * m <= np.median(white) <= 1.25 * m
            iso = np.mean(np.sum(e**2, axis=2), axis=1)
            old = [excess(x, float(np.mean(np.trace(V, axis1=1, axis2=2))), 20) for x in iso]
            assert np.mean(np.array(old) > 0) < 0.5  # what the finding was about
        else:
            iso = np.mean(np.sum(e**2, axis=2), axis=1)
            old = [excess(x, float(np.mean(np.trace(V, axis1=1, axis2=2))), 20) for x in iso]
            assert np.mean(np.array(old) > 0) > 0.06
    assert whitened_excess(np.zeros((0, 3)), np.zeros((0, 3, 3))) == 0.0


def _paired_scene(rng: np.random.Generator):
    """A linear calibration of 6 parameters from two frames (12 pixel rows each, unit white
    noise; the first carries nearly all the information), one new view at the first frame's
    posture paired with it and three new views elsewhere, their columns three times the
    frames'; every view's tool-mount columns its parameters' (the mount's directed tests look
    along them). The views (residuals zero), the estimate's covariance, the frames' columns and
    the unpaired views'."""
    p, k2, n = 6, 12, 3
    Hb = [rng.standard_normal((k2, p)) * s for s in (3.0, 0.3)]
    C = np.linalg.inv(sum(H.T @ H for H in Hb))
    Hu = [rng.standard_normal((k2, p)) * 3.0 for _ in range(3)]
    rows = np.arange(k2)

    def view(H: np.ndarray, local: np.ndarray, **kw) -> ViewJacobians:
        return ViewJacobians(r=np.zeros(k2), local=local, kin=H, cam=np.zeros((k2, 0)), tool=H,
                             world=rng.standard_normal((k2, 6)), joints=rng.standard_normal((k2, n)),
                             B=np.eye(6), Ad=np.eye(6), tw=np.zeros((6, n)), **kw)  # fmt: skip

    views = [view(Hb[0], 2.0 * np.eye(k2), paired=True, frame=(0, rows, np.eye(k2)), frame_H=Hb[0])]
    return views + [view(H, np.eye(k2)) for H in Hu], C, Hb, Hu


def _paired_residuals(C, Hb, Hu, draws, rng):
    """``draws`` stacked residuals of the scene's new views under "unchanged": the paired one
    ``e_new - e_frame`` (the estimate's error cancels), the others ``e_u - H_u (theta_hat -
    theta)``, the estimate's error from the frames' noise (least squares)."""
    k2 = len(Hb[0])
    e = rng.standard_normal((draws, len(Hb), k2))
    new = rng.standard_normal((draws, 1 + len(Hu), k2))
    delta = sum(e[:, i] @ H for i, H in enumerate(Hb)) @ C
    return np.concatenate([new[:, 0] - e[:, 0]] + [new[:, i + 1] - delta @ H.T for i, H in enumerate(Hu)],
                          axis=1)  # fmt: skip


def test_a_paired_view_shares_its_frames_noise_in_the_estimate_with_the_others():
    """4000 draws of the scene: whitened by the check's covariance with the cross term ``H_b C
    H_u^T`` the residuals' covariance has its eigenvalues in 0.80-1.21 (what 4000 draws of 48
    white coordinates spread to), and the first 200 checks at alpha 0.2 call 17.5 % changed
    (the Bonferroni combination is conservative, docs/tool-accuracy.md); without it 0.32-1.78
    (the paired difference and the unpaired residuals move together along the frame's columns)
    and 31 % changed, the mount's directed tests beyond their level."""
    rng = np.random.default_rng(1)
    views, C, Hb, Hu = _paired_scene(rng)
    R = _paired_residuals(C, Hb, Hu, 4000, rng)
    spread = {}
    for label, C_noise in (("with", C), ("without", None)):
        W = np.linalg.solve(np.linalg.cholesky(_covariance(C, views, C_noise)), R.T).T
        ev = np.linalg.eigvalsh(np.cov(W.T))
        spread[label] = (ev.min(), ev.max())
    assert 0.7 <= spread["with"][0] and spread["with"][1] <= 1.35
    assert spread["without"][1] > 1.5  # the review's finding 6
    k2 = len(views[0].r)
    alarms = [image_drift_check(C, [dataclasses.replace(v, r=r[i * k2 : (i + 1) * k2])
                                    for i, v in enumerate(views)],
                                eye_to_hand=False, alpha=0.2, C_noise=C).changed
              for r in R[:200]]  # fmt: skip
    assert np.mean(alarms) <= 0.26


def test_the_check_takes_the_folds_whitened_excess_where_the_block_gives_it():
    """The block's ``whitened_excess_mm`` / ``_deg`` is the second null's size; a file written
    before it keeps the squared norms' rule (here 0.80 mm held out against 0.2 mm estimation
    and 0.1 mm noise over 30 rows: an excess of 0.45 mm per coordinate)."""
    old = {"held_out_rms_mm": 0.80, "estimation_rms_mm": 0.2, "noise_mm": 0.1, "rows": 30}
    pos, rot = fold_excess({"model_error": old})
    assert pos * 1e3 == pytest.approx(np.sqrt((0.80**2 - 0.2**2 - 3 * 0.1**2) / 3)) and rot == 0.0
    new = old | {"whitened_excess_mm": 0.3, "whitened_excess_deg": 0.05}
    assert fold_excess({"model_error": new}) == pytest.approx((3e-4, np.radians(0.05)))
    assert fold_excess({"model_error": old | {"whitened_excess_mm": 0.0}}) == (0.0, 0.0)
