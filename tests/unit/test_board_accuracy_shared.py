"""Whether two robots' board accuracy draws of one seed share their chance
(selfcal.benchmarks.board.accuracy_shared, issue #29)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy_shared import main, shared, shared_lines
from selfcal.errors import UsageError

SD = np.array([2.0, 1.0, 0.5, 3.0, 1.5])
"""The synthetic draws' predicted standard deviations: three kinematic parameters (each turns
the orientation about its own axis), then the camera's ``cx`` and ``cy``."""


def _draw(z: np.ndarray) -> dict:
    """A draw whose parameter errors are ``z`` (5,) predicted standard deviations."""
    J = np.stack([np.eye(3), np.eye(3)])
    dp = z * SD
    return {"status": "ok", "names": ["a", "b", "c", "cx", "cy"], "error": dp,
            "cov": np.diag(SD**2), "J": J, "e_rot": np.einsum("mij,j->mi", J, dp[:3])}  # fmt: skip


def _pairs(rho: float, seeds: int = 300) -> tuple[list[dict], list[dict]]:
    """Two robots' draws over ``seeds`` seeds whose standard normals correlate by ``rho``."""
    rng = np.random.default_rng(3)
    x, y = rng.standard_normal((2, seeds, 5))
    return [_draw(v) for v in x], [_draw(rho * v + np.sqrt(1 - rho**2) * w) for v, w in zip(x, y)]


def test_draws_that_share_their_noise_correlate_and_independent_ones_do_not():
    """The same standard normals: every correlation 1; independent ones: every correlation
    within the 90 % null range's 1.5 times (300 seeds, so about +-0.14); half-shared normals:
    the camera's correlations near 0.5 (the whitened error, a sum of squares, near 0.25)."""
    same = shared(*_pairs(1.0))
    assert same["u"][0] == pytest.approx(1.0) and same["whitened"][0] == pytest.approx(1.0)
    assert same["camera"]["cx"][0] == pytest.approx(1.0)
    none = shared(*_pairs(0.0))
    assert none["null"] == pytest.approx(1.645 / np.sqrt(299))
    for r in (none["u"][0], none["whitened"][0], *(v[0] for v in none["camera"].values())):
        assert abs(r) < 1.5 * none["null"]
    half = shared(*_pairs(0.5))
    assert set(half["camera"]) == {"cx", "cy"}
    assert all(0.35 < r < 0.65 for r, _ in half["camera"].values())
    assert 0.1 < half["whitened"][0] < 0.45
    lines = shared_lines(half, "t")
    assert lines[0].startswith("t: 300 seeds") and "cx +0." in lines[2]


def test_a_seed_with_a_failed_draw_is_left_out_and_too_few_seeds_are_refused():
    """A failed draw drops its seed from both robots; fewer than 4 seeds: refused, saying so."""
    a, b = _pairs(0.0, seeds=6)
    b[0] = {"status": "failed: X"}
    assert shared(a, b)["seeds"] == 5
    with pytest.raises(UsageError, match="at least 4"):
        shared(a[:4], b[:4])


def test_two_robots_are_needed():
    """``--robots`` names two robots: one is refused before any draw runs."""
    with pytest.raises(UsageError, match="two robots"):
        main(["--robots", "ur5e", "--draws", "1"])
