"""The simulated images' sensor noise (``selfcal.sim.render.noise_field``): drawn as integers,
it must have the distribution of a Gaussian rounded to the grey levels (what float normals
added, rounded and clipped gave), stay seeded, and saturate at 0 and 255."""

import numpy as np
import pytest
from scipy.stats import chi2

from selfcal.errors import InputError
from selfcal.sim.render import (
    apply_noise,
    noise_field,
    rounded_gaussian_pmf,
    rounded_gaussian_table,
)

SHAPE = (480, 640, 3)  # one image of the default scenario: 921,600 draws


def _chi_square(z: np.ndarray, sigma: float) -> tuple[float, int]:
    """Pearson's chi-square of the integers ``z`` against the rounded Gaussian of std ``sigma``
    (tails pooled until each bin expects >= 20 draws) and its degrees of freedom."""
    k, pmf = rounded_gaussian_pmf(sigma)
    counts = np.bincount(z.ravel() - k[0], minlength=len(k))
    assert len(counts) == len(k), "a draw outside the pmf's support"
    expected = pmf * z.size
    keep = np.flatnonzero(expected >= 20)
    lo, hi = keep[0], keep[-1]
    obs = np.r_[counts[: lo + 1].sum(), counts[lo + 1 : hi], counts[hi:].sum()]
    exp = np.r_[expected[: lo + 1].sum(), expected[lo + 1 : hi], expected[hi:].sum()]
    return float(((obs - exp) ** 2 / exp).sum()), len(obs) - 1


@pytest.mark.parametrize("sigma", [0.7, 2.0, 3.0])
def test_the_drawn_integers_follow_the_rounded_gaussian(sigma):
    z = noise_field(SHAPE, sigma, np.random.default_rng(11))
    assert z.shape == SHAPE
    stat, dof = _chi_square(z, sigma)
    assert chi2.sf(stat, dof) > 1e-3, f"chi-square {stat:.1f} on {dof} degrees of freedom"
    # the moments of the rounded Gaussian: mean 0, variance sigma**2 + 1/12 (Sheppard)
    assert abs(z.mean()) < 4 * sigma / np.sqrt(z.size)
    assert z.std() == pytest.approx(np.sqrt(sigma**2 + 1 / 12), rel=3e-3)


def test_a_32_bit_generator_draws_the_same_distribution():
    """MT19937 makes 32 bits a draw: all 64 bits of each word must still be random (its raw
    output left the high half 0: a chi-square of 2.6e9). Seed 12: seed 11's draw
    lies at p = 0.001, seeds 12-30 at chi-square 8-28 on 16 degrees of freedom."""
    z = noise_field(SHAPE, 2.0, np.random.Generator(np.random.MT19937(12)))
    stat, dof = _chi_square(z, 2.0)
    assert chi2.sf(stat, dof) > 1e-3, f"chi-square {stat:.1f} on {dof} degrees of freedom"


def test_the_chi_square_tells_a_noise_one_percent_too_strong():
    """The test above can fail: 2.02 grey levels' draws are rejected against 2.0's pmf."""
    z = noise_field(SHAPE, 2.02, np.random.default_rng(11))
    stat, dof = _chi_square(z, 2.0)
    assert chi2.sf(stat, dof) < 1e-6


LAGS = (1, 2, 3, 4, 5, 8, SHAPE[1] * SHAPE[2])  # neighbours, channels, pixels and the next row


def _lag_correlations(z: np.ndarray) -> np.ndarray:
    """The correlation of the flattened draws ``z`` with themselves shifted by each of LAGS."""
    x = z.ravel().astype(np.float64)
    x -= x.mean()
    return np.array([np.dot(x[:-k], x[k:]) / np.dot(x, x) for k in LAGS])


@pytest.mark.parametrize("bits", ["PCG64", "MT19937"])
def test_the_draws_are_uncorrelated(bits):
    """Independent draws (the sensor noise is i.i.d. per pixel and channel): each lag's
    correlation within 4 standard errors (1/sqrt(n)) of 0; the chi-square above cannot see a
    draw repeated or shared between neighbours."""
    rng = np.random.Generator(getattr(np.random, bits)(13))
    z = noise_field(SHAPE, 2.0, rng)
    r = _lag_correlations(z)
    assert np.abs(r).max() < 4 / np.sqrt(z.size), dict(zip(LAGS, r.round(5)))


def test_the_correlation_test_tells_repeated_draws():
    """The test above can fail: every draw used twice (a table index reused) correlates
    neighbours at 0.5, draws shared a row apart likewise."""
    z = noise_field(SHAPE, 2.0, np.random.default_rng(13))
    twice = np.repeat(z.ravel()[: z.size // 2], 2).reshape(SHAPE)
    assert _lag_correlations(twice)[0] > 0.4
    rows = z.copy()
    rows[1::2] = rows[::2]
    assert _lag_correlations(rows)[-1] > 0.4


def test_the_table_is_the_pmf_to_its_resolution():
    for sigma in (0.5, 2.0, 64.0):
        k, pmf = rounded_gaussian_pmf(sigma)
        table = rounded_gaussian_table(sigma)
        share = np.bincount(table - k[0], minlength=len(k)) / len(table)
        assert np.abs(share - pmf).max() <= 2.0**-16
        assert table.min() == -table.max()  # symmetric, as the pmf


def test_the_noise_is_seeded():
    a = noise_field(SHAPE, 2.0, np.random.default_rng(3))
    b = noise_field(SHAPE, 2.0, np.random.default_rng(3))
    c = noise_field(SHAPE, 2.0, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert (a != c).mean() > 0.5


def test_applied_noise_saturates_at_the_grey_levels_ends():
    img = np.repeat(np.array([0, 1, 128, 254, 255], np.uint8), 20_000).reshape(-1, 1)
    z = noise_field(img.shape, 3.0, np.random.default_rng(5))
    want = np.clip(img.astype(int) + z, 0, 255)
    out = apply_noise(img, z.copy())
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, want)
    assert out.min() == 0 and out.max() == 255


def test_a_sigma_not_above_zero_is_refused():
    with pytest.raises(InputError, match="must be > 0"):
        rounded_gaussian_table(0.0)
