"""Robust triangulation (selfcal.estimation.triangulation.robust_triangulate): the current point
short-cuts the vote without changing any outcome."""

from __future__ import annotations

import numpy as np

from selfcal.camera import Pinhole
from selfcal.estimation.reprojection import reprojection_residuals
from selfcal.estimation.triangulation import robust_triangulate
from selfcal.transforms import make_pose


def _scene(seed: int = 0):
    """12 cameras around 6 points, every point seen by every camera, 0.3 px noise, and one gross
    outlier row of point 1."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-0.2, 0.2, (6, 3))
    T = []
    for a in np.linspace(-0.6, 0.6, 12):
        c, s = np.cos(a), np.sin(a)
        R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        T.append(make_pose(R, np.array([0.0, 0.0, 1.0])))
    T = np.stack(T)
    cam = Pinhole.centered(800.0, 1.0, 640, 480)
    view, pidx = np.meshgrid(np.arange(12), np.arange(6), indexing="ij")
    view, pidx = view.ravel(), pidx.ravel()
    r, _ = reprojection_residuals(cam, T, X, view, pidx, np.zeros((len(view), 2)))
    uv = r + rng.normal(0, 0.3, r.shape)
    uv[np.flatnonzero(pidx == 1)[3]] += 40.0
    return T, view, pidx, uv, cam, X


def test_a_current_point_that_explains_every_row_leaves_the_other_points_as_they_were():
    T, view, pidx, uv, cam, X_true = _scene()
    cur = np.full((6, 3), np.nan)
    cur[0] = X_true[0]  # explains all its rows: its samples are not scored
    X_a, inl_a = robust_triangulate(T, view, pidx, uv, cam, 6, 3.0, X_current=cur, seed=4)
    X_b, inl_b = robust_triangulate(T, view, pidx, uv, cam, 6, 3.0, seed=4)
    # point 0: the refit on all its rows either way; the others drew the same samples
    np.testing.assert_array_equal(X_a, X_b)
    np.testing.assert_array_equal(inl_a, inl_b)
    assert inl_a[pidx == 0].all() and inl_a.sum() == len(view) - 1  # the outlier is out
    np.testing.assert_allclose(X_a, X_true, atol=2e-3)


def test_a_current_point_with_an_outlier_row_still_takes_the_vote():
    """X_current pulled by 1 cm explains only some rows: the samples vote, and the point and its
    inliers come out as without X_current."""
    T, view, pidx, uv, cam, X_true = _scene(1)
    cur = X_true + np.array([0.01, 0.0, 0.0])
    X_a, inl_a = robust_triangulate(T, view, pidx, uv, cam, 6, 3.0, X_current=cur, seed=2)
    X_b, inl_b = robust_triangulate(T, view, pidx, uv, cam, 6, 3.0, seed=2)
    np.testing.assert_allclose(X_a, X_b, atol=1e-12)
    np.testing.assert_array_equal(inl_a, inl_b)
