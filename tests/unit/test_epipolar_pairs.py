"""Which view pairs the epipolar stage estimates (selfcal.estimation.epipolar): every qualifying
pair counted up to DENSE_VIEWS views, a uniform draw of them above (linear in the views)."""

from __future__ import annotations

import numpy as np

import selfcal.estimation.epipolar as epipolar
from selfcal.calibration.field.synthetic import synthetic_stereo_scene
from selfcal.estimation.epipolar import _all_pairs, _sampled_pairs, fundamental_pairs
from selfcal.estimation.observations import ViewLayout


def _vis(n_frames: int, seed: int = 0) -> np.ndarray:
    """(2 n_frames, 60) a stereo rig's views each seeing a random window of 30 of 60 points."""
    rng = np.random.default_rng(seed)
    start = rng.integers(0, 30, 2 * n_frames)
    return (np.arange(60)[None] >= start[:, None]) & (np.arange(60)[None] < start[:, None] + 30)


def test_sampled_pairs_are_qualifying_pairs_in_order_with_every_rig_pair():
    lay = ViewLayout(400, 2)
    vis = _vis(400)
    iu, ju, best = _all_pairs(vis, 20)
    su, sj, sbest = _sampled_pairs(vis, lay, 20, 150, np.random.default_rng(1))
    every = set(zip(iu.tolist(), ju.tolist()))
    drawn = list(zip(su.tolist(), sj.tolist()))
    assert set(drawn) <= every and len(set(drawn)) == len(drawn)
    assert drawn == sorted(drawn)
    rig = lay.same_frame(su, sj)
    assert int(rig.sum()) == int(lay.same_frame(iu, ju).sum())  # every qualifying rig pair
    assert int((~rig).sum()) == 150
    assert sbest <= best == 30


def test_sampled_pairs_cover_the_qualifying_pairs_uniformly():
    """Over many draws, pairs of frames far apart (few of them qualify) come as often as their
    share of the qualifying pairs says."""
    lay = ViewLayout(100, 2)
    vis = _vis(100, seed=2)
    iu, ju, _ = _all_pairs(vis, 20)
    other = ~lay.same_frame(iu, ju)
    far = np.abs(iu - ju)[other] > 100
    want = far.mean()
    got = []
    for seed in range(40):
        su, sj, _ = _sampled_pairs(vis, lay, 20, 150, np.random.default_rng(seed))
        o = ~lay.same_frame(su, sj)
        got.append(np.mean(np.abs(su - sj)[o] > 100))
    assert abs(np.mean(got) - want) < 0.03, (np.mean(got), want)


def test_pairs_on_two_threads_are_the_pairs_one_by_one(monkeypatch):
    """The pairs estimated on two threads are the pairs estimated one after another, in the
    same order, to the bit (OpenCV's estimators do not depend on the thread)."""
    obs = synthetic_stereo_scene(12, seed=3, noise_px=0.5).observations()
    monkeypatch.setattr(epipolar, "helper_threads", lambda jobs, cap=None: 2)
    threaded = fundamental_pairs(obs, max_pairs=40)
    monkeypatch.setattr(epipolar, "helper_threads", lambda jobs, cap=None: 1)
    serial = fundamental_pairs(obs, max_pairs=40)
    assert len(threaded) == len(serial) > 20
    for t, s in zip(threaded, serial, strict=True):
        assert (t.view_a, t.view_b, t.n_h_inliers) == (s.view_a, s.view_b, s.n_h_inliers)
        assert np.array_equal(t.F, s.F) and np.array_equal(t.pidx, s.pidx)
        assert np.array_equal(t.inlier, s.inlier) and np.array_equal(t.sampson_px, s.sampson_px)
