"""The board accuracy Monte Carlo's look inside a row: the orientation covariance's directions
(selfcal.benchmarks.board.accuracy_parts, issue #29)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy_parts import (
    bound_check,
    directions,
    first_point,
    kept_draw,
    main,
    table,
)
from selfcal.errors import UsageError


def _draw(dp: np.ndarray) -> dict:
    """A draw whose parameters' covariance is diag(4, 1, 0.25) and whose orientation moves
    with each parameter about its own axis (J = I at two joint vectors)."""
    J = np.stack([np.eye(3), np.eye(3)])
    return {"status": "ok", "names": ["a", "b", "c"], "error": dp, "cov": np.diag([4.0, 1.0, 0.25]),
            "J": J, "e_rot": np.einsum("mij,j->mi", J, dp)}  # fmt: skip


def test_the_directions_are_the_covariances_largest_orientation_parts():
    """Each direction's share is its variance's part of the predicted orientation variance,
    largest first; an error of one standard deviation along the first is z = +-1 there and 0
    elsewhere; the realised over the predicted mean square is the error's part (4 of 5.25)."""
    d = directions(_draw(np.array([2.0, 0.0, 0.0])))
    assert d["share"] == pytest.approx(np.array([4.0, 1.0, 0.25]) / 5.25)
    assert d["z"] ** 2 == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert np.abs(d["load"][:, 0]) == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert d["ratio"] == pytest.approx(4.0 / 5.25)
    assert d["linear"] < 1e-12


def test_an_error_not_carried_to_the_orientation_shows_in_linear():
    """A true orientation error the parameters' Jacobian does not give (another frame or
    convention) is the ``linear`` misfit: here all of it."""
    g = _draw(np.array([2.0, 0.0, 0.0]))
    g["e_rot"] = -g["e_rot"]
    assert directions(g)["linear"] == pytest.approx(2.0)


def test_the_table_counts_failed_draws_and_lists_every_parameter():
    """The table names the draws, the failed ones and every parameter's mean z and z^2."""
    text = table([_draw(np.array([2.0, -1.0, 0.5])), {"status": "failed: X"}], "t")
    assert "1 draws (1 failed)" in text
    assert "| a | +1.00 | 1.00 |" in text and "| b | -1.00 | 1.00 |" in text
    assert "| all 3 | +0.33 | 1.00 |" in text


def _draws(scale: float, count: int = 400) -> list[dict]:
    """``count`` draws of :func:`_draw` whose parameter errors are ``scale`` times a sample of
    their covariance diag(4, 1, 0.25) (seeded)."""
    rng = np.random.default_rng(7)
    return [_draw(scale * rng.standard_normal(3) * np.array([2.0, 1.0, 0.5])) for _ in range(count)]


def test_the_bound_check_of_errors_drawn_from_the_prediction_finds_it_right():
    """Errors drawn from the predicted covariance: the bound covers about 95 %, the integral
    transform is uniform (mean 0.5 +- 0.014 for 400 draws, the KS test passes), the count beyond
    the bound is inside a right bound's range and the realised mean square is the predicted one;
    Satterthwaite's quantile of this anisotropic covariance is the exact one within 1 %."""
    b = bound_check(_draws(1.0))
    assert b["draws"] == 400
    assert 0.93 <= b["coverage"] <= 0.97
    assert abs(b["pit_mean"] - 0.5) < 0.04 and b["pit_ks_p"] > 0.05
    assert b["beyond_range"][0] <= b["beyond"] <= b["beyond_range"][1]
    assert b["ratio_range"][0] < 1.0 < b["ratio_range"][1]
    assert abs(b["quantile_excess"][0]) < 0.01


def test_the_bound_check_finds_a_bound_twice_too_wide():
    """Errors half the predicted size: nearly all covered, the transform piled low (KS fails),
    almost no draw beyond the bound and a realised mean square a quarter of the predicted."""
    b = bound_check(_draws(0.5))
    assert b["coverage"] > 0.99 and b["pit_mean"] < 0.3 and b["pit_ks_p"] < 1e-6
    assert b["beyond"] < b["beyond_range"][0] and b["beyond_p"] < 0.01
    assert b["ratio_range"][1] < 0.3


def test_a_kept_draw_is_read_back_as_it_was_kept(tmp_path):
    """``--keep``: a draw kept in the folder under its robot, noise, seed and truth by the code
    checked out is read from there (no calibration run), its status and names as strings, its
    arrays equal."""
    g = _draw(np.array([2.0, -1.0, 0.5])) | {"code": "abc1234"}
    np.savez(
        tmp_path / "ur5e_0.2px_seed7_truthNone.npz", **{k: np.asarray(v) for k, v in g.items()}
    )
    got = kept_draw(("ur5e", 0.2, 7, None, tmp_path, "abc1234"))
    assert got["status"] == "ok" and got["names"] == ["a", "b", "c"]
    assert np.array_equal(got["cov"], g["cov"]) and np.array_equal(got["e_rot"], g["e_rot"])


@pytest.mark.parametrize(
    ("kept_by", "code"),
    [
        ("0123456", "abc1234"),  # kept by other code
        (None, "abc1234"),  # kept before the code was recorded
        ("abc1234+changes", "abc1234+changes"),  # uncommitted changes: not the same code
    ],
)
def test_a_draw_kept_by_other_code_is_drawn_again(tmp_path, monkeypatch, kept_by, code):
    """``--keep`` never reuses a draw that the code checked out did not draw (review of session
    23: the file's name holds robot, noise, seed and truth only): it is drawn again and kept in
    its place with this code."""
    from selfcal.benchmarks.board import accuracy_parts as board_accuracy_parts

    old = _draw(np.array([2.0, -1.0, 0.5])) | ({"code": kept_by} if kept_by else {})
    path = tmp_path / "ur5e_0.2px_seed7_truthNone.npz"
    np.savez(path, **{k: np.asarray(v) for k, v in old.items()})
    new = _draw(np.array([0.1, 0.2, 0.3]))
    monkeypatch.setattr(board_accuracy_parts, "draw_parts", lambda args: dict(new))
    got = kept_draw(("ur5e", 0.2, 7, None, tmp_path, code))
    assert np.array_equal(got["error"], new["error"])
    with np.load(path) as z:
        assert str(z["code"]) == code and np.array_equal(z["error"], new["error"])


def test_a_fixed_truth_and_a_noise_offset_are_refused_together():
    """``--fixed-truth`` and ``--noise-offset`` say two things about the truths: refused before
    any draw runs."""
    with pytest.raises(UsageError, match="--noise-offset"):
        main(["--fixed-truth", "1", "--noise-offset", "500", "--draws", "1"])


def test_the_whitened_error_is_a_chi_square_with_three_degrees_of_freedom():
    """Errors drawn from the prediction: the whitened error's mean over 400 draws is 3 within
    3 of its standard errors (sqrt(6 / 400) = 0.12); errors half the size: a quarter of it."""
    assert abs(bound_check(_draws(1.0))["whitened"] - 3.0) < 3 * np.sqrt(6 / 400)
    assert bound_check(_draws(0.5))["whitened"] == pytest.approx(
        bound_check(_draws(1.0))["whitened"] / 4
    )
    u, w = first_point(_draw(np.array([2.0, 1.0, 0.5])))
    assert w == pytest.approx(3.0) and 0.0 < u < 1.0
