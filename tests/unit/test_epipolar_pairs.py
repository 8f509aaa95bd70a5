"""Which view pairs the epipolar stage estimates (selfcal.estimation.epipolar): every qualifying
pair counted up to DENSE_VIEWS views, a uniform draw of them above (linear in the views)."""

from __future__ import annotations

import numpy as np

from selfcal.estimation.epipolar import _all_pairs, _sampled_pairs
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
