"""The model error's growth with the distance from the calibration postures, read from held-out
rows (selfcal.calibration.growth, issue #29)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.accuracy import Z_MODEL_ERROR, model_error_of, unmeasured_beyond
from selfcal.calibration.growth import fit_variogram
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.robot.definition import load_robot


def _rows(level: float, growth: float, seed: int, k: int = 60) -> tuple[np.ndarray, ...]:
    """Held-out 3-vectors at distances 0.05-0.5 whose error per coordinate has the variance
    ``noise^2 + level + growth d^2`` (m^2), the noise known: the tracker route's excess
    ``|r|^2 - 3 noise^2``, its variance without a model error ``2/3 (3 noise^2)^2``."""
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.05, 0.5, k)
    noise = 1e-4
    sd = np.sqrt(noise**2 + level + growth * d**2)
    r = rng.normal(size=(k, 3)) * sd[:, None]
    excess = np.sum(r**2, axis=1) - 3 * noise**2
    var = np.full(k, 2.0 / 3.0 * (3 * noise**2) ** 2)
    return excess, var, np.full(k, 3.0), 3.0 * d**2, d


def test_a_growing_model_error_is_found():
    level, growth = (0.5e-4) ** 2, (8e-4) ** 2  # 0.05 mm, growing by 0.8 mm per unit distance
    got = [fit_variogram(*_rows(level, growth, seed), Z_MODEL_ERROR) for seed in range(20)]
    assert all(g.shown for g in got)
    slope = np.sqrt(np.clip([g.estimate for g in got], 0.0, None))
    assert np.median(slope) == pytest.approx(8e-4, rel=0.1)
    # counted: its upper bound, unless that alone explains more than the rows' excess
    assert all(g.growth >= g.estimate or g.level == 0.0 for g in got)
    # at the far end of the held-out rows the counted size is the true one (median of 20)
    far = np.sqrt([g.at(0.5) for g in got])
    assert np.median(far) == pytest.approx(np.sqrt(level + growth * 0.25), rel=0.02)


def test_a_constant_model_error_gives_no_growth():
    level = (3e-4) ** 2
    got = [fit_variogram(*_rows(level, 0.0, seed), Z_MODEL_ERROR) for seed in range(40)]
    # one-sided two standard errors: a false growth in about 1 fit in 40
    assert sum(g.shown for g in got) <= 3
    assert abs(np.median([g.t for g in got])) < 0.5  # the estimate ~0
    # the size at the rows' mean distance is the level; the counted growth is only its upper
    # bound, which at the rows' far end (0.5) adds less than the level itself (median)
    assert np.median(np.sqrt([g.at(0.275) for g in got])) == pytest.approx(3e-4, rel=0.05)
    assert 0 < np.median([g.growth * 0.25 / g.level for g in got]) < 1.5


def _unmeasured(gram, measured_to: float | None, d: np.ndarray) -> np.ndarray:
    """Where a tool-error prediction whose model error the rows ``gram`` read (None: the
    same everywhere) out to the distance ``measured_to`` (None: not read) says it is not
    measured, at the distances ``d`` (the first joint moved, in units of a unit span): the
    production path, the route's ModelError carried into the ToolErrorModel
    (selfcal.calibration.accuracy.unmeasured_beyond)."""
    rows = [np.full(4, 1e-8)]
    me = model_error_of(rows, rows, rows, None, folds=1, failed=0, noise_what="noise",
                        given=(1e-4, None), reach_distance=0.1, growth=gram,
                        measured_to=measured_to)  # fmt: skip
    assert me is not None
    model = nominal_mcpc(load_robot("er4u-paper"))
    q_cal = np.zeros((1, model.n))
    em = ToolErrorModel(model, np.eye(4), np.arange(0), np.zeros((0, 0)), 1e-4,
                        reach_postures=q_cal, reach_span=np.ones(model.n), reach_distance=0.1,
                        measured_to=unmeasured_beyond(me))  # fmt: skip
    q = np.zeros((len(d), model.n))
    q[:, 0] = d
    return em.unmeasured(q)


def test_beyond_what_the_folds_measured():
    excess, var, a, b, d = _rows((3e-4) ** 2, 0.0, 1)
    flat = fit_variogram(excess, var, a, b, d, Z_MODEL_ERROR)
    assert not flat.shown
    to = float(np.max(d))  # the rows' largest distance (0.5 at most)
    far = np.array([0.1, to + 0.01, 1.0])
    assert _unmeasured(flat, to, far).tolist() == [False, True, True]
    grown = fit_variogram(*_rows(0.0, (8e-4) ** 2, 1), Z_MODEL_ERROR)
    assert grown.shown and grown.floor(0.3) < 0.1
    # shown or not, beyond the rows' largest distance it is not measured
    assert _unmeasured(grown, to, far).tolist() == [False, True, True]
    assert not _unmeasured(None, None, far).any()  # not read: no limit


def test_held_out_rows_at_training_postures_measure_nothing_beyond_them():
    """Held-out rows all at their folds' training postures (largest distance 0) tested the
    model nowhere beyond them: everything farther is not measured, in the ModelError and through
    its calibration.json block (0 is a limit; only a distance not read means none)."""
    flat = fit_variogram(*_rows((3e-4) ** 2, 0.0, 1), Z_MODEL_ERROR)
    far = np.array([0.0, 1e-3, 0.1, 1.0])
    assert _unmeasured(flat, 0.0, far).tolist() == [False, True, True, True]
    assert _unmeasured(None, 0.0, far).tolist() == [False, True, True, True]
    rows = [np.full(4, 1e-8)]
    me = model_error_of(rows, rows, rows, None, folds=1, failed=0, noise_what="noise",
                        measured_to=0.0)  # fmt: skip
    assert me is not None and me.limit == 0.0
    assert unmeasured_beyond(me.to_json()) == 0.0


def test_distances_all_alike_cannot_show_a_growth():
    excess, var, a, _, d = _rows((3e-4) ** 2, 0.0, 2)
    same = np.full_like(d, 0.2)
    got = fit_variogram(excess, var, a, 3.0 * same**2, same, Z_MODEL_ERROR)
    assert not got.shown and got.growth == 0.0 and got.floor(0.2) == 1.0
    assert got.level == pytest.approx(np.sum(excess) / np.sum(a))


def test_the_unit_of_the_distance_does_not_matter():
    """Distances in another unit (here 1e-4 of it: the growth's column 1e8 times smaller than
    the level's) give the same fit in that unit, not a flat one: the test for distances all
    alike is made on the columns scaled to unit size."""
    excess, var, a, b, d = _rows(0.0, (8e-4) ** 2, 1)
    got = fit_variogram(excess, var, a, b, d, Z_MODEL_ERROR)
    small = fit_variogram(excess, var, a, b * 1e-8, d * 1e-4, Z_MODEL_ERROR)
    assert got.shown and small.shown
    assert small.t == pytest.approx(got.t, rel=1e-6)
    assert small.growth == pytest.approx(got.growth * 1e8, rel=1e-6)
    assert small.at(d * 1e-4) == pytest.approx(got.at(d), rel=1e-6)


def test_a_pooled_variance_is_carried_to_the_mean_distance():
    """A second quantity of the same rows that grows the same way (the tracker's orientation
    beside its position), known only pooled over the rows: carried by the position's variogram
    to the rows' mean distance it is its true variance there (median over 40 seeded draws, 1.003
    of it; one draw's ratio spreads 0.16), where the pooled one overstates it by mean(d^2) /
    mean(d)^2 (1.22 for distances even in 0.05-0.5; 1.20 here)."""
    growth, k = (8e-4) ** 2, 0.25  # the second quantity's variance: k times the first's
    carried, pooled, truth = [], [], []
    for seed in range(40):
        excess, var, a, b, d = _rows(0.0, growth, seed)
        gram = fit_variogram(excess, var, a, b, d, Z_MODEL_ERROR)
        rng = np.random.default_rng(seed + 100)
        second = np.sum(rng.normal(size=(d.size, 3)) ** 2, axis=1) * k * growth * d**2
        reach = float(np.mean(d))
        pooled.append(np.mean(second) / 3.0)
        carried.append(pooled[-1] * gram.carried(d, reach))
        truth.append(k * growth * reach**2)
    assert np.median(np.divide(carried, truth)) == pytest.approx(1.0, abs=0.01)  # 1.003
    assert 1.15 < np.median(np.divide(pooled, truth)) < 1.25  # 1.20
