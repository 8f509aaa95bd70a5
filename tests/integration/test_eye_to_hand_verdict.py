"""The eye-to-hand run's verdict against the truth (``selfcal.pipeline.static_report``, issue
#29's drift benchmark): analytic draws of the UR5e's cell at 0.2 px (the benchmark's
``simulated_calibration``) that a check of one figure marked failed.

- A calibration that IS the fair nominal: postures of one arm configuration (the wrist alone
  moves) cannot check any kinematic parameter on postures it was not fitted to, so the selection
  keeps none and the calibration is the fair nominal by construction, on every draw the route
  calibrates (seed 26 of the 30-posture plan was such a case only by its folds' dealing, which
  changed when the configurations were numbered by their joints). The two predicted the
  validation board poses equal but for rounding, which a strict comparison called "worse".
  Now: ok, no gain in either figure.
- Seed 25 (30 postures): the calibration predicts the kinematic part (the flange centre after
  the rigid alignment) better than the fair nominal (0.103 against 0.153 mm RMS) and the
  unaligned board pose slightly worse (1.128 against 1.097 mm), the difference along the
  camera's axis (its focal length's depth, which both fit). Now: ok, no gain in the camera frame.
- Seed 2 (30 postures): the other way round (flange centre 0.230 against 0.206 mm, board pose
  1.096 against 2.467 mm); a check of the aligned figure alone failed it. Now: ok, no gain in
  the kinematic part. Worse in both figures still fails.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from selfcal.acquisition.eye_to_hand import static_cell
from selfcal.benchmarks.board.accuracy import prior
from selfcal.config.scenario import load_scenario
from selfcal.io.board_calibration import read_board_calibration
from selfcal.io.truth import read_truth
from selfcal.pipeline.run import run_all
from selfcal.pipeline.static_report import static_truth_report
from selfcal.robot.definition import load_robot
from selfcal.sim.static_camera import plan_static_postures

pytestmark = pytest.mark.slow  # an analytic calibration each: ~15-30 s


WRIST_POSTURES = 10
"""Postures of the one arm configuration of the NO GAIN case (the wrist alone moves)."""


def _report(tmp_path, seed: int, *, one_configuration: bool = False) -> dict:
    """The run's report.json of the draw ``seed`` (the run in ``tmp_path / "run"``): the
    benchmark's 30 postures (6 arm configurations of 5 wrist orientations), or with
    ``one_configuration`` :data:`WRIST_POSTURES` wrist orientations of one configuration (a
    joints file the scenario replays)."""
    over = {"noise": {"render": False, "pixel_sigma": 0.2, "seed": seed},
            "trajectory": {"poses": 30, "seed": seed}, "perturbation": {"seed": seed}}  # fmt: skip
    if one_configuration:
        over["trajectory"] |= {"kind": "file", "joints": str(_wrist_only(tmp_path, seed))}
    s = load_scenario("eye-to-hand", over)
    out = tmp_path / "run"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_all(s, out, quiet=True, figures=False, deviation=prior(s))  # used to raise
    return json.loads((out / "report.json").read_text())


def _wrist_only(tmp_path, seed: int):
    """A joints file (deg) of :data:`WRIST_POSTURES` postures of one arm configuration of the
    cell, planned as the scenario plans its configurations (its nominal cell, ``seed``)."""
    s = load_scenario("eye-to-hand")
    robot = load_robot(s.robot.model)
    q = plan_static_postures(static_cell(s, robot, nominal=True), 1, WRIST_POSTURES, seed=seed)
    path = tmp_path / "wrist.csv"
    np.savetxt(path, np.degrees(q), delimiter=",", fmt="%.6f", comments="",
               header=",".join(f"j{j + 1}" for j in range(q.shape[1])))  # fmt: skip
    return path


def test_a_calibration_that_is_the_fair_nominal_is_no_gain_not_a_failure(tmp_path):
    """One arm configuration, 10 wrist orientations (seed 1): the calibration is the fair
    nominal. Seeds 1-6 scanned (``_report(tmp, seed, one_configuration=True)``): 1, 2, 3, 5
    and 6 are the fair nominal to 1e-13, NO GAIN in both figures; seed 4's wrist postures do not
    determine the mounts (the board route stops with an IdentificationError: rank deficient at
    the solution), which says so rather than returning a number."""
    rep = _report(tmp_path, 1, one_configuration=True)
    assert rep["frames"]["used"] == rep["frames"]["planned"] == WRIST_POSTURES
    assert rep["status"] == "ok" and rep["failures"] == []
    a = rep["validation"]["flange_centre_aligned_mm"]
    v = rep["validation"]["board_pose_in_camera"]
    assert a["calibrated"]["rms"] == pytest.approx(a["nominal"]["rms"], rel=1e-9)
    assert v["calibrated"]["position_mm"]["rms"] == pytest.approx(
        v["nominal"]["position_mm"]["rms"], rel=1e-9
    )
    assert len(rep["identified"]) == 12  # base -> camera and flange -> board alone
    assert [n.split(":")[0] for n in rep["notes"]] == ["NO GAIN in the camera frame",
                                                      "NO GAIN in the kinematic part"]  # fmt: skip
    assert all("is the fair nominal" in n for n in rep["notes"])
    # a chain worse in both figures still fails: joint 2's alpha 2 mrad off (measured 0.153
    # against 0.118 mm aligned, 1.618 against 0.988 mm unaligned; on seed 3's postures the
    # same change made the unaligned figure better, 5.740 against 5.833 mm: base -> camera's
    # own error is in it, so a change worse in both is a property of the draw, checked here)
    root = tmp_path / "run"
    cal = read_board_calibration(root / "calibration.json")
    p = cal.model.params.copy()
    p[2, 0] += 0.002
    bad = dataclasses.replace(cal, model=cal.model.with_params(p))
    got = static_truth_report(root, bad, read_truth(root / "truth.json"))
    assert got["status"] == "failed" and "worse than the fair nominal in both" in got["failures"][0]


@pytest.mark.parametrize(("seed", "no_gain"), [(25, "camera frame"), (2, "kinematic part")])
def test_one_figure_worse_and_the_other_better_is_no_gain_in_that_one(tmp_path, seed, no_gain):
    rep = _report(tmp_path, seed)
    assert rep["status"] == "ok" and rep["failures"] == []
    a = rep["validation"]["flange_centre_aligned_mm"]
    v = rep["validation"]["board_pose_in_camera"]
    pairs = {"kinematic part": (a["calibrated"]["rms"], a["nominal"]["rms"]),
             "camera frame": (v["calibrated"]["position_mm"]["rms"],
                              v["nominal"]["position_mm"]["rms"])}  # fmt: skip
    lost = pairs.pop(no_gain)
    (won,) = pairs.values()
    assert lost[0] > lost[1] and won[0] < 0.8 * won[1]  # 25: 0.103 / 0.153 mm; 2: 1.096 / 2.467
    (note,) = rep["notes"]
    assert note.startswith(f"NO GAIN in the {no_gain}: ") and "flange centre after" in note
