"""``calibrate(DIR, terms=[ProbeTerm(...)])``: images and touch-probe points in one calibration.

A simulated SCORBOT dataset (analytic path: projected corners with 0.5 px noise, exact joint
read-back) whose probe tip (the true tool tip, on the camera's side of the flange) touched known
points of a fixture at the dataset's postures (0.02 mm per coordinate). The calibration takes the
probe as one more term: the result records its section, whose fit is the touches' noise and
whose tip is the true tip in the calibrated camera frame; the calibrated chain with that tip
predicts the tip at the held-out joints far better than the nominal chain (the arm's joint offset
and link errors recovered), and the section reads back as its type.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from selfcal.calibration.field.calibrate import calibrate
from selfcal.config.scenario import load_scenario
from selfcal.io.calibration import write_calibration
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.pipeline.run import run_acquire
from selfcal.robot.definition import load_robot
from selfcal.terms import registry
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.transforms import pose_from_vec, trans

SIGMA_M = 2e-5


@pytest.mark.slow  # an acquisition and a field calibration: ~25 s on 2 loaded cores
def test_touch_probe_points_calibrate_with_the_images(tmp_path):
    noise = {"render": False, "pixel_sigma": 0.5, "seed": 4, "quantize_joints": False}
    run_acquire(load_scenario(overrides={"noise": noise}), tmp_path, quiet=True)
    ds = Dataset.open(tmp_path)
    truth = read_truth(tmp_path / "truth.json")
    q = np.radians(ds.joints_deg)
    T_fixture_world = pose_from_vec([0.4, -1.1, 0.3, 0.5, -0.7, 0.2])
    tips = tool_tips(truth.true_model, q, truth.T_cam_tip)
    p = tips @ T_fixture_world[:3, :3].T + T_fixture_world[:3, 3]
    p += np.random.default_rng(5).normal(0.0, SIGMA_M, p.shape)
    probe = ProbeTerm(q, p, np.arange(len(q)), SIGMA_M, file="touches.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate(tmp_path, terms=[probe])
    sec = res.section("probe")
    assert isinstance(sec, ProbeSection) and sec.touches == len(q)
    print(sec.summary())
    # the fit is the touches' noise (3-D RMS of 0.02 mm per coordinate: 0.035 mm); measured 0.028
    assert sec.rms_mm < 2 * np.sqrt(3) * 1e3 * SIGMA_M
    # the tip in the calibrated camera frame: the true tip to the camera frame's own error
    off = np.linalg.norm(np.asarray(sec.tip_mm) - 1e3 * truth.T_cam_tip[:3, 3])
    # held-out tool tips: the calibrated chain and estimated tip against the nominal chain
    qv = np.radians(ds.info.validation_joints_deg)
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    robot = load_robot(ds.info.robot_model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    e_nom = aligned_errors(tool_tips(nominal, qv, truth.T_cam_tip), p_true)["rms"]
    e_cal = aligned_errors(tool_tips(res.model, qv, trans(np.asarray(sec.tip_mm) / 1e3)), p_true)
    print(f"tip {off:.3f} mm off; held-out tip RMS nominal {e_nom:.3f}, calibrated "
          f"{e_cal['rms']:.4f} mm")  # fmt: skip
    assert off < 0.4  # measured 0.140 mm
    assert e_nom > 1.0 and e_cal["rms"] < 0.025  # measured 1.58 and 0.0087 mm
    # calibration.json: sources and the section, read back as its type
    path = write_calibration(tmp_path / "calibration.json", res)
    back = registry.read_calibration(path)
    assert back.to_json()["sources"] == ["images", "probe"]
    assert isinstance(back.section("probe"), ProbeSection)
    assert back.section("probe").to_json() == sec.to_json()
