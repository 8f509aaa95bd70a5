"""Image observations (selfcal.estimation.observations): the view arithmetic in one place and its round trips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from selfcal.estimation.observations import Observations, RowGroups, ViewLayout, views_per_point
from selfcal.target import Features


@given(st.integers(1, 50), st.integers(1, 6), st.data())
def test_view_index_round_trips(n_frames, n_cameras, data):
    lay = ViewLayout(n_frames, n_cameras)
    views = np.arange(lay.n_views)
    np.testing.assert_array_equal(lay.view(lay.frame(views), lay.camera(views)), views)
    f = data.draw(st.integers(0, n_frames - 1))
    c = data.draw(st.integers(0, n_cameras - 1))
    v = int(lay.view(f, c))
    assert (int(lay.frame(v)), int(lay.camera(v))) == (f, c)
    a = np.arange(lay.n_views * 2.0).reshape(lay.n_views, 2)
    by = lay.by_frame(a)
    assert by.shape == (n_frames, n_cameras, 2)
    np.testing.assert_array_equal(by[f, c], a[v])
    np.testing.assert_array_equal(lay.by_view(by), a)
    np.testing.assert_array_equal(lay.of_camera(a, c), by[:, c])
    np.testing.assert_array_equal(lay.per_view(np.arange(n_frames)), lay.frame(views))
    assert bool(lay.same_frame(v, lay.view(f, n_cameras - 1)))
    reg = np.zeros(lay.n_views, bool)
    reg[v] = True
    assert lay.frame_any(reg)[f] and lay.frame_any(reg).sum() == 1
    assert lay.frame_all(reg).sum() == (1 if n_cameras == 1 else 0)


def test_of_camera_writes_through():
    lay = ViewLayout(3, 2)
    T = np.zeros((lay.n_views, 4, 4))
    lay.of_camera(T, 1)[:] = 7.0
    np.testing.assert_array_equal(lay.by_frame(T)[:, 1], 7.0)
    np.testing.assert_array_equal(lay.by_frame(T)[:, 0], 0.0)


def test_views_per_point_counts_distinct_views():
    view = np.array([0, 0, 1, 3, 3, 2])
    pidx = np.array([0, 0, 0, 1, 1, 2])  # point 0 twice in view 0
    np.testing.assert_array_equal(views_per_point(view, pidx, 4), [2, 1, 1, 0])
    np.testing.assert_array_equal(views_per_point(view[:0], pidx[:0], 2), [0, 0])


def test_views_per_point_table_and_sort_agree(monkeypatch):
    """The (point, view) table of small problems counts as the sort of larger ones does."""
    import selfcal.estimation.observations as observations

    rng = np.random.default_rng(3)
    view, pidx = rng.integers(0, 40, 500), rng.integers(0, 30, 500)  # repeats within views
    table = views_per_point(view, pidx, 32)
    monkeypatch.setattr(observations, "SEEN_TABLE_MAX", 0)
    np.testing.assert_array_equal(table, views_per_point(view, pidx, 32))
    assert table[30:].tolist() == [0, 0] and table.max() < 40


def test_observations_from_features_for_one_and_three_cameras():
    f = Features([5, 9], [[1.0, 2.0], [3.0, 4.0]])
    one = Observations.from_features({(0, 0): f, (2, 0): f}, cameras=("cam",))
    assert one.n_cameras == 1 and one.n_configs == 3 and one.n_views == 3
    np.testing.assert_array_equal(one.view, [0, 0, 2, 2])
    three = Observations.from_features(
        {(1, "top"): f, (0, 0): f}, n_configs=2, cameras=("left", "right", "top")
    )
    np.testing.assert_array_equal(three.view, [5, 5, 0, 0])
    np.testing.assert_array_equal(three.layout.camera(three.view), three.camera)
    np.testing.assert_array_equal(three.layout.frame(three.view), three.config)
    ids, idx = three.point_index()
    np.testing.assert_array_equal(ids[idx], three.point)
    sub = three.subset(three.camera == 2)
    assert len(sub) == 2 and sub.n_cameras == 3 and sub.n_configs == 2
    with pytest.raises(ValueError, match="not one of"):
        Observations.from_features({(0, "middle"): f})
    with pytest.raises(ValueError, match="camera indices"):
        Observations(np.zeros(1, int), np.full(1, 2), np.zeros(1, int), np.zeros((1, 2)), 1, 2)


def test_observations_from_marker_corners():
    det = {(0, "left"): {3: np.arange(8.0).reshape(4, 2)}, (2, 1): {5: np.ones((4, 2))}}
    obs = Observations.from_corners(det)
    assert obs.n_configs == 3 and obs.n_cameras == 2 and len(obs) == 8
    np.testing.assert_array_equal(obs.point, [12, 13, 14, 15, 20, 21, 22, 23])
    np.testing.assert_array_equal(obs.uv[:4], np.arange(8.0).reshape(4, 2))
    with pytest.raises(ValueError, match="twice"):
        Observations(np.zeros(2, int), np.zeros(2, int), np.array([4, 4]), np.zeros((2, 2)), 1)
    with pytest.raises(ValueError, match="NaN"):
        Observations.from_corners({(0, 0): {1: np.full((4, 2), np.nan)}})
    with pytest.raises(ValueError, match="shape"):
        Observations.from_corners({(0, 0): {1: np.zeros((3, 2))}})


def test_row_groups_give_the_rows_a_scan_gives():
    """RowGroups (the initial reconstruction's per-view and per-point rows, found without a
    scan of every row) returns exactly what flatnonzero over all rows returns, in row order,
    also for empty groups and no keys."""
    rng = np.random.default_rng(3)
    key = rng.integers(0, 40, 1000)
    key[key == 7] = 8  # key 7 has no rows
    g = RowGroups(key, 41)  # key 40: none either
    for k in (0, 7, 8, 39, 40):
        assert np.array_equal(g.rows_of_one(k), np.flatnonzero(key == k))
    for keys in ([], [5], [3, 7, 40, 1], rng.permutation(41)[:17]):
        want = np.flatnonzero(np.isin(key, keys))
        assert np.array_equal(g.rows_of(np.asarray(keys, int)), want)
