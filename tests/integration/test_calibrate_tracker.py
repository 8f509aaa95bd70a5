"""``selfcal calibrate DATASET --tracker FILE``: images and tracker measurements of the same
postures in one estimate, from the command line (issue #13).

A simulated SCORBOT dataset (analytic path: projected corners with 0.5 px noise, exact joint
read-back) and a tracker file of the same postures as a lab would write it (joints in degrees,
the tool tip in the tracker frame in mm, 0.1 mm noise, an arbitrary tracker frame). Three
estimates, each through the command line: the images alone (``selfcal calibrate``), the tracker
alone (``selfcal identify`` + ``selfcal predict``) and both (``selfcal calibrate --tracker``).
Metric: the tool-tip error they predict on the dataset's validation postures after the best
rigid alignment (:func:`selfcal.kinematics.accuracy.aligned_errors`, as ``selfcal report``).
"""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest

from selfcal.cli.main import main as cli_main
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.kinematics.forward import fk_tool
from selfcal.terms.registry import read_calibration
from selfcal.transforms import pose_from_vec, trans

SIGMA_MM = 0.1
T_TRACKER_WORLD = pose_from_vec([0.4, -1.1, 0.3, 1.5, -0.7, 0.2])


def _write_rows(path, header, rows) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


@pytest.fixture(scope="module")
def acquired(tmp_path_factory, default_exact_joints):
    """The dataset (not calibrated: a copy of the one tests/conftest.py acquires once per test
    run), the tracker file of its postures and the validation joints."""
    tmp = tmp_path_factory.mktemp("ct")
    images = tmp / "images"
    shutil.copytree(default_exact_joints, images)
    ds = Dataset.open(images)
    truth = read_truth(images / "truth.json")
    q_deg = np.asarray(ds.joints_deg)
    tips = tool_tips(truth.true_model, np.radians(q_deg), truth.T_cam_tip)
    xyz = tips @ T_TRACKER_WORLD[:3, :3].T + T_TRACKER_WORLD[:3, 3]
    xyz_mm = 1e3 * xyz + np.random.default_rng(5).normal(0.0, SIGMA_MM, xyz.shape)
    joints = [f"j{i + 1}" for i in range(q_deg.shape[1])]
    tracker = tmp / "tracker.csv"
    _write_rows(tracker, [*joints, "x_mm", "y_mm", "z_mm"], np.c_[q_deg, xyz_mm].tolist())
    validation = tmp / "validation_joints.csv"
    _write_rows(validation, joints, ds.info.validation_joints_deg.tolist())
    return tmp, images, tracker, validation, truth, ds, xyz_mm


@pytest.fixture(scope="module")
def both(acquired):
    """A copy of the dataset calibrated with the tracker file."""
    tmp, images, tracker, *_ = acquired
    out = tmp / "both"
    shutil.copytree(images, out)
    argv = ["calibrate", str(out), "-q", "--tracker", str(tracker), "--joint-units", "deg"]
    assert cli_main(argv) == 0
    return out


@pytest.mark.slow  # two more estimates (images alone, tracker alone): 17 s on a loaded machine
def test_images_and_tracker_together_are_at_least_as_good_as_either_alone(acquired, both):
    tmp, images, tracker, validation, truth, ds, _ = acquired
    assert cli_main(["calibrate", str(images), "-q"]) == 0
    argv = ["identify", str(tracker), "--robot", ds.info.robot_model, "--joint-units", "deg"]
    assert cli_main([*argv, "--out", str(tmp / "trk"), "-q"]) == 0
    predicted = tmp / "predicted.csv"
    argv = ["predict", str(tmp / "trk"), "--joints", str(validation), "--joint-units", "deg"]
    assert cli_main([*argv, "--out", str(predicted), "-q"]) == 0
    qv = np.radians(ds.info.validation_joints_deg)
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    cal_img, cal_both = read_calibration(images), read_calibration(both)
    assert cal_img.section("tracker") is None and cal_both.section("tracker") is not None
    e_images = aligned_errors(tool_tips(cal_img.model, qv, truth.T_cam_tip), p_true)["rms"]
    tool = trans(np.asarray(cal_both.section("tracker").tool_point_mm) / 1e3)
    e_both = aligned_errors(tool_tips(cal_both.model, qv, tool), p_true)["rms"]
    p_trk = np.loadtxt(predicted, delimiter=",", skiprows=1) / 1e3
    e_tracker = aligned_errors(p_trk, p_true)["rms"]
    print(f"tool tip RMS mm: images {e_images:.4f}, tracker {e_tracker:.4f}, both {e_both:.4f}")
    # measured: images 0.203, tracker 0.092, both 0.030 mm
    assert e_both <= min(e_images, e_tracker)
    assert e_both < 0.09  # 3x the measured 0.030 mm


def test_calibration_json_records_both_sources(acquired, both):
    _, _, tracker, _, truth, ds, xyz_mm = acquired
    doc = json.loads((both / "calibration.json").read_text())
    assert doc["sources"] == ["images", "tracker"] and doc["status"] == "ok"
    t = doc["tracker"]
    assert t["file"] == str(tracker) and t["joint_units"] == "deg"
    assert t["kinds"] == ["positions"] and t["rows"] == len(ds.indices) and t["distances"] == 0
    assert t["sigma_mm"] == pytest.approx(SIGMA_MM)
    # the fit is the noise: measured 0.15 mm (3-D RMS of 0.1 mm per coordinate: 0.17 mm)
    assert t["rms_mm"]["positions"] < 2 * np.sqrt(3) * SIGMA_MM
    # the recorded tracker frame (world = the reference left camera) and tool point predict the
    # measured positions from the calibrated chain: to the noise (measured 0.15 mm RMS)
    cal = read_calibration(both)
    T = np.asarray(t["T_tracker_world_m"]) @ fk_tool(cal.model, np.radians(ds.joints_deg))
    p = T[:, :3, :3] @ (np.asarray(t["tool_point_mm"]) / 1e3) + T[:, :3, 3]
    rms = np.sqrt(np.mean(np.sum((1e3 * p - xyz_mm) ** 2, axis=1)))
    print(f"tracker fit {t['rms_mm']['positions']:.4f} mm, recomputed {rms:.4f} mm")
    assert rms == pytest.approx(t["rms_mm"]["positions"], rel=1e-3)
    # the tool point lies near the true tip in the camera frame (measured 0.2 mm off: the
    # estimated camera frame's own error, which the tool point absorbs)
    off = np.linalg.norm(np.asarray(t["tool_point_mm"]) - 1e3 * truth.T_cam_tip[:3, 3])
    print(f"tool point {off:.3f} mm from the true tip")
    assert off < 0.5  # 2.7x the measured 0.185 mm


def test_tracker_options_are_checked(acquired, capsys):
    _, images, tracker, *_ = acquired
    assert cli_main(["calibrate", str(images), "--tracker", str(tracker)]) == 2
    assert "--joint-units" in capsys.readouterr().err
    assert cli_main(["calibrate", str(images), "--joint-units", "deg"]) == 2
    assert "needs --tracker" in capsys.readouterr().err
    argv = ["calibrate", str(images), "--tracker", str(tracker), "--joint-units", "deg"]
    assert cli_main([*argv, "--method", "two-stage"]) == 2
    assert "--method joint" in capsys.readouterr().err
    assert cli_main([*argv, "--tracker-sigma-mm", "0"]) == 2
    assert "--tracker-sigma-mm must be a positive number" in capsys.readouterr().err
    # without --tracker the noise would weigh nothing (a --term takes its own): refused
    argv = ["calibrate", str(images), "--term", f"tracker={tracker}", "--joint-units", "deg"]
    assert cli_main([*argv, "--tracker-sigma-mm", "0.05"]) == 2
    assert "tracker=FILE,sigma_mm=0.05" in capsys.readouterr().err
