"""The eye-to-hand run's verdict against the truth (``selfcal.pipeline.static_report``, issue
#29's drift benchmark): analytic draws of the UR5e's cell at 0.2 px (the benchmark's
``simulated_calibration``, 30 postures) that a check of one figure marked failed.

- Seed 26: cross-validation keeps no kinematic parameter, so the calibration IS the fair nominal;
  the two predicted the validation board poses 4.196001995420988 and 4.19600199542082 mm RMS,
  and the strict comparison called the rounding "worse". Now: ok, no gain in either figure.
- Seed 25: the calibration predicts the kinematic part (the flange centre after the rigid
  alignment) better than the fair nominal (0.103 against 0.153 mm RMS) and the unaligned board
  pose slightly worse (1.128 against 1.097 mm), the difference along the camera's axis (its
  focal length's depth, which both fit). Now: ok, no gain in the camera frame.
- Seed 2: the other way round (flange centre 0.230 against 0.206 mm, board pose 1.096 against
  2.467 mm); a check of the aligned figure alone failed it. Now: ok, no gain in the kinematic
  part. Worse in both figures still fails.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import pytest

from selfcal.benchmarks.board_accuracy import prior
from selfcal.config.scenario import load_scenario
from selfcal.io.board_calibration import read_board_calibration
from selfcal.io.truth import read_truth
from selfcal.pipeline.run import run_all
from selfcal.pipeline.static_report import static_truth_report

pytestmark = pytest.mark.slow  # an analytic calibration each: ~15-30 s


def _report(tmp_path, seed: int) -> dict:
    """The run's report.json of the draw ``seed`` (the run in ``tmp_path / "run"``)."""
    over = {"noise": {"render": False, "pixel_sigma": 0.2, "seed": seed},
            "trajectory": {"poses": 30, "seed": seed}, "perturbation": {"seed": seed}}  # fmt: skip
    s = load_scenario("eye-to-hand", over)
    out = tmp_path / "run"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_all(s, out, quiet=True, figures=False, deviation=prior(s))  # used to raise
    return json.loads((out / "report.json").read_text())


def test_a_calibration_that_is_the_fair_nominal_is_no_gain_not_a_failure(tmp_path):
    rep = _report(tmp_path, 26)
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
    # a chain worse in both figures still fails: joint 2's alpha 2 mrad off (measured 0.306
    # and 5.040 mm; a 2 mm longer link made the unaligned figure better, 4.162 mm: base ->
    # camera's own error is in it)
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
