"""What `selfcal plan` shows of its forecast's draws (selfcal/cli/plan_forecast.py,
selfcal/plots/plan_figure.py): the percentiles' Monte Carlo standard error is the spread a
percentile of that many draws has from seed to seed, and the figure carries the draws' own
median and 90th percentile in its legend, laid out without overlaps."""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.plan.spread import SelectionSpread
from selfcal.plots.plan_figure import plan_spread_figure, spread_words
from selfcal.plots.plotting import figure_problems


def _spread(rng: np.random.Generator, n: int, scale: float) -> SelectionSpread:
    tool = scale * np.abs(rng.standard_normal(n)) + scale / 4  # m, skewed as the draws are
    chosen = np.ones(n, np.int64)
    chosen[rng.permutation(n)[: n * 3 // 20]] = 0  # 15 % keep the smaller set
    return SelectionSpread(tool, chosen, ("nominal", "all"))


def test_the_standard_error_is_the_seed_to_seed_spread_of_a_percentile():
    rng = np.random.default_rng(3)
    runs = [_spread(rng, 400, 1e-3) for _ in range(300)]
    for p in (50, 90):
        seen = np.std([r.percentile(p) for r in runs])
        said = np.median([r.standard_error(p) for r in runs])
        assert 0.75 < said / seen < 1.33, (p, said, seen)


def test_the_figure_shows_the_draws_numbers():
    rng = np.random.default_rng(5)
    plan, rand = _spread(rng, 400, 0.6e-3), _spread(rng, 400, 1.7e-3)
    fig = plan_spread_figure([("the plan of 12", plan), ("a random plan of 12", rand)], 1.408,
                             "the chain as drawn", "title")  # fmt: skip
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    for label, sp in (("the plan of 12", plan), ("a random plan of 12", rand)):
        (mine,) = [t for t in texts if t.startswith(label + ":")]
        assert spread_words(sp) in mine
        assert f"median {1000 * np.median(sp.tool_m):.3f} mm" in mine
        assert "kept in 15 % of draws" in mine
    assert any("1.408 mm (the chain as drawn)" in t for t in texts)
    assert figure_problems(fig) == []


def test_sets_far_apart_are_drawn_on_a_log_axis():
    """--add to a poorly identified dataset: 40 mm before, 0.2 mm after (the real Nachi set):
    on a linear axis the after's curve is a vertical line at zero."""
    rng = np.random.default_rng(7)
    before, after = _spread(rng, 400, 40e-3), _spread(rng, 400, 0.2e-3)
    fig = plan_spread_figure([("before", before), ("after", after)], 5.1, "the chain as drawn",
                             "title")  # fmt: skip
    ax = fig.axes[0]
    assert ax.get_xscale() == "log"
    lo, hi = ax.get_xlim()
    assert lo < 1000 * after.tool_m.min() and hi > 1000 * before.tool_m.max()
    assert figure_problems(fig) == []
    near = plan_spread_figure([("plan", after), ("random", after)], 0.5, "x", "title")
    assert near.axes[0].get_xscale() == "linear"


def test_a_plan_behind_the_random_one_by_the_draws_is_named():
    """Forecast.behind: a sentence with both medians when the plan's median is not below the
    random plan's (selfcal plan warns with it), None when it is."""
    from selfcal.cli.plan_forecast import DrawSet, Forecast

    rng = np.random.default_rng(5)
    q = np.zeros((6, 6))
    small, large = _spread(rng, 400, 1e-3), _spread(rng, 400, 3e-3)
    plan, rand = DrawSet("plan", "the plan of 6", q), DrawSet("random", "a random plan of 6", q)
    assert Forecast(((plan, small), (rand, large)), 400, 0).behind("plan", "random") is None
    said = Forecast(((plan, large), (rand, small)), 400, 0).behind("plan", "random")
    assert said is not None and "the plan of 6" in said and "--count" in said
    assert f"{1000 * large.percentile(50):.3f} mm" in said
    assert f"{1000 * small.percentile(50):.3f} mm" in said
