"""The noise-reference benchmark's share of five-view checks called noisy
(selfcal.benchmarks.drift.noise_reference, issue #29): at the views' own noise it is the level
the check sets (1 - (1 - 0.01 / 5)^5), and a reference 3 % low at 68 degrees of freedom a
view calls more than three times as many checks noisy (tests/unit/test_drift_view_noise.py
draws them: 64 of 2000)."""

from __future__ import annotations

import pytest

from selfcal.benchmarks.drift.noise_reference import noisy_share
from selfcal.calibration.drift.views import WHITE_LEVEL


def test_the_share_is_the_level_at_the_views_noise_and_grows_as_the_reference_falls():
    assert noisy_share(0.1, 0.1, 68) == pytest.approx(1 - (1 - WHITE_LEVEL / 5) ** 5, rel=1e-9)
    low = noisy_share(0.097, 0.1, 68)
    assert 3.0 < low / noisy_share(0.1, 0.1, 68) < 3.6  # 3.35x
    assert noisy_share(0.103, 0.1, 68) < noisy_share(0.1, 0.1, 68)
