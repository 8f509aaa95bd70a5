"""The board route's bootstrap over arm configurations (selfcal.calibration.board.bootstrap):
resamples independent of the frames' order and fixed by the seed, the spread's formula, failed
refits counted and said. The refits themselves: tests/integration/test_board_analytic.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.calibration.board.bootstrap import (
    BoardFitInputs,
    bootstrap_spread,
    canonical_frames,
    refit_row,
    resamples,
)
from selfcal.calibration.board.folds import configurations
from selfcal.calibration.spread import SpreadPoints, spread_line
from selfcal.pipeline.board_accuracy import spread_markdown
from selfcal.target.base import Features

TYPES = ("revolute",) * 6


def _frames(seed: int = 0) -> tuple[np.ndarray, list[Features]]:
    """8 arm configurations, 1-3 frames each (the wrist turned), a distinct detection each."""
    rng = np.random.default_rng(seed)
    q, feats = [], []
    for _ in range(8):
        arm = rng.uniform(-1, 1, 3)
        for _ in range(rng.integers(1, 4)):
            q.append(np.concatenate([arm, rng.uniform(-1, 1, 3)]))
            ids = np.sort(rng.choice(40, 12, replace=False))
            feats.append(Features(ids, rng.uniform(0, 640, (12, 2))))
    return np.array(q), feats


def _drawn(q: np.ndarray, feats: list[Features], seed: int, count: int = 5) -> list[list]:
    """What each resample holds: its frames' joints and detections, in the refit's order."""
    groups = canonical_frames(q, feats, TYPES)
    return [[(tuple(q[i]), tuple(feats[i].ids), feats[i].uv.tobytes()) for i in pick]
            for pick in resamples(groups, count, seed)]  # fmt: skip


def test_the_resamples_do_not_depend_on_the_order_of_the_frames():
    """The same frames shuffled give the same resamples, frame for frame in the same order."""
    q, feats = _frames()
    perm = np.random.default_rng(3).permutation(len(q))
    assert _drawn(q[perm], [feats[i] for i in perm], seed=7) == _drawn(q, feats, seed=7)


def test_the_configurations_are_the_folds_numbering_also_when_their_first_joints_tie():
    """Two configurations whose first joints lie within 0.1 deg (the folds' tolerance) are
    told apart by the next joint and numbered as the folds number them (by the arm joints of
    their first frame in joint order), whatever the order of the frames; a frame within 0.1 deg
    of a configuration's first frame joins it. Frames (A, A', B): A' 0.09 deg past A on the
    first joint, B 0.03 deg past A (its mean first joint below A's and A'`s mean: a numbering by
    the mean arm joints would put B first), its second joint 0.5 rad away."""
    d = np.radians(0.01)
    q = np.array([[0.0, 0.2, 0.0, 0.1, 0.0, 0.0],  # A
                  [9 * d, 0.2, 0.0, -0.3, 0.0, 0.0],  # A', the wrist turned
                  [3 * d, 0.7, 0.0, 0.0, 0.0, 0.0]])  # B  # fmt: skip
    rng = np.random.default_rng(1)
    feats = [Features(np.arange(12), rng.uniform(0, 640, (12, 2))) for _ in q]
    assert configurations(q, TYPES).tolist() == [0, 0, 1]
    for perm in ([0, 1, 2], [2, 1, 0], [1, 2, 0]):
        groups = canonical_frames(q[perm], [feats[i] for i in perm], TYPES)
        assert [np.array(perm)[g].tolist() for g in groups] == [[0, 1], [2]]


def test_the_seed_fixes_the_resamples_and_each_holds_whole_configurations():
    """Same seed, same resamples; another seed, others. Every resample draws as many
    configurations as there are (with replacement) and takes all of a drawn one's frames."""
    q, feats = _frames()
    assert _drawn(q, feats, seed=1) == _drawn(q, feats, seed=1)
    assert _drawn(q, feats, seed=1) != _drawn(q, feats, seed=2)
    groups = canonical_frames(q, feats, TYPES)
    assert sorted(np.concatenate(groups).tolist()) == list(range(len(q)))
    size = {int(i): len(g) for g in groups for i in g}
    for pick in resamples(groups, 20, seed=5):
        arms = [tuple(np.round(q[i, :3], 9)) for i in pick]
        for a in set(arms):  # each drawn configuration with all its frames, k times
            first = pick[arms.index(a)]
            assert arms.count(a) % size[int(first)] == 0
        assert sum(arms.count(a) // size[int(pick[arms.index(a)])] for a in set(arms)) == 8


def test_the_spread_is_the_bootstraps_standard_error_and_failed_refits_are_counted():
    """Tool points +-d apart along x over B refits: spread^2 = sum |t_b - mean|^2 / (B - 1),
    per joint vector; two failed refits are counted with their reason in the block and the
    line."""
    d = np.array([0.001, 0.002, 0.004])  # m, three joint vectors
    signs = [1.0, -1.0, 1.0, -1.0]
    ok = [{"tips": {"inside": np.column_stack([s * d, np.zeros(3), np.zeros(3)])}}
          for s in signs]  # fmt: skip
    fail = {"failed": "EstimationError: too few configurations"}
    outcomes = [*ok, fail, fail]
    block = bootstrap_spread(outcomes, seed=3, configurations=8).to_json()
    expected = np.sqrt(4 * d**2 / 3) * 1e3
    got = block["regions"]["inside"]
    assert got["spread_mm_max"] == pytest.approx(expected.max())
    assert got["spread_mm_median"] == pytest.approx(np.median(expected))
    assert got["spread_mm_rms"] == pytest.approx(np.sqrt(np.mean(expected**2)))
    assert block["resamplings"] == 4 and block["failed"] == 2 and block["requested"] == 6
    assert block["failures"] == [{"reason": "EstimationError: too few configurations", "count": 2}]
    assert block["method"] == "bootstrap" and block["seed"] == 3 and block["selection"] == "held"
    assert "model selection held" in block["what"]
    line = spread_line(block)
    assert "4 bootstrap refits of the 8 arm configurations" in line
    assert "(seed 3; model selection held)" in line
    assert (
        "the estimation spread of the calibration's chosen model" in spread_markdown(block, None)[1]
    )
    assert "2 refit(s) failed" in line and "too few configurations" in line


def test_with_fewer_than_two_refits_no_spread_is_given_and_that_is_said():
    one = {"tips": {"inside": np.zeros((3, 3))}}
    block = bootstrap_spread([one, {"failed": "X"}], seed=0, configurations=8).to_json()
    assert block["regions"] == {} and block["resamplings"] == 1 and block["failed"] == 1
    assert spread_line(block).startswith("no run-to-run spread over 1 bootstrap refits")


def test_a_refit_that_cannot_be_made_is_a_failed_row_with_its_reason():
    """A resample whose images show no board: the refit's error is the row, not an exception."""
    from selfcal.config.scenario import load_scenario, scenario_board
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot

    s = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / "mono-charuco.toml")
    board = scenario_board(s)
    robot = load_robot(s.robot.model)
    q = np.zeros((8, robot.n))
    empty = Features(np.zeros(0, dtype=np.int64), np.zeros((0, 2)))
    inputs = BoardFitInputs(board, (empty,) * 8, q, nominal_mcpc(robot), (640, 480), "pinhole",
                            ("fx", "mu", "cx", "cy"), tuple(f"f{i}" for i in range(8)), None,
                            None, False)  # fmt: skip
    points = SpreadPoints({"inside": q[:2]}, np.eye(4))
    row = refit_row({"inputs": inputs, "pick": np.arange(8), "points": points})
    assert set(row) == {"failed"} and "BoardInputError" in row["failed"]


def test_the_spread_figure_shows_the_runs_numbers_without_overlap():
    """figures/spread.png: nothing cut off or overlapping (figure_problems), every bar's number
    written from the block, the run's count, configurations and seed in the title."""
    from selfcal.plots.plotting import figure_problems
    from selfcal.plots.spread_figure import spread_figure

    tips = [{"tips": {"inside": np.full((3, 3), s * 1e-3), "edge": np.full((2, 3), s * 2e-3)}}
            for s in (1.0, -1.0, 0.5)]  # fmt: skip
    boot = bootstrap_spread(tips, seed=4, configurations=9).to_json()
    jack = {"regions": {"inside": {"spread_mm_rms": 0.25, "spread_mm_max": 0.3}}}
    acc = {"bootstrap_spread": boot, "spread": jack,
           "regions": {"inside": {"position_rms_mm": 0.4}, "edge": {"position_rms_mm": 0.5}}}  # fmt: skip
    fig = spread_figure(acc)
    assert figure_problems(fig) == []
    texts = {t.get_text() for t in fig.axes[0].texts}
    want = [boot["regions"]["inside"]["spread_mm_rms"], 0.25, 0.4, 0.5]
    assert all(f"{v:.3f}" in texts for v in want), texts
    assert (
        "3 bootstrap refits of 9 arm configurations (seed 4, 0 failed)" in fig.axes[0].get_title()
    )


def test_the_parameters_a_refit_keeps_are_found_by_their_names():
    """The held refit's parameters by name (parameter_indices): the pool's own names give back
    its flat MCPC indices and joint offsets, in the names' order; a name the chain does not
    offer is an error, not a parameter silently left out."""
    from selfcal.calibration.board.parameter_pool import parameter_indices, parameter_pool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot

    robot = load_robot("ur5e")
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    q = np.random.default_rng(2).uniform(-1.5, 1.5, (12, robot.n))
    order = parameter_pool(model, q).order[::-1]  # any order: kept as given
    idx, joints = parameter_indices(model, [nm for nm, _, _ in order])
    assert idx.tolist() == [i for _, kind, i in order if kind == "mcpc"]
    assert joints.tolist() == [i for _, kind, i in order if kind == "offset"]
    assert len(idx) + len(joints) == len(order) and len(joints) > 0
    with pytest.raises(KeyError):
        parameter_indices(model, ["offset_j9"])


def test_refits_that_fitted_other_parameters_are_counted_and_said():
    """Held (the default): a refit whose resample could not determine a chosen parameter fits
    fewer and is counted; free: a refit whose selection chose another set is counted, and the
    line says which of the two it is."""
    tip = {"inside": np.zeros((2, 3))}
    outcomes = [{"tips": tip, "parameters": ["a", "b"]}, {"tips": tip, "parameters": ["b", "a"]},
                {"tips": tip, "parameters": ["a"]}, {"failed": "X"}]  # fmt: skip
    held = bootstrap_spread(outcomes, seed=0, configurations=8, chosen=("a", "b")).to_json()
    assert held["refits_other_parameters"] == 1 and held["selection"] == "held"
    assert "1 refit(s) held some of the chosen parameters at the fair nominal" in spread_line(held)
    free = bootstrap_spread(outcomes, seed=0, configurations=8, chosen=("a", "b"), held=False)
    block = free.to_json()
    assert block["selection"] == "free" and "its own parameter selection" in block["what"]
    assert "1 refit(s) selected other kinematic parameters" in spread_line(block)
    assert "model selection held" not in spread_line(block)
