"""``selfcal identify`` / ``selfcal predict`` on chains other than a 5- or 6-axis arm, each judged
against the fair nominal (the robot file's chain with the tracker frame and the tool fitted).

- A 2-axis positioner (tests/data/positioner2.toml) measured by a pose sensor, its file in the
  scalar-last quaternion order (qx, qy, qz, qw) a ROS tool writes: before, refused with
  "2 joints; a robot needs 3 to 7".
- A 7-axis arm (tests/data/arm7.toml) measured by positions.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.tracker.sim import make_case, measure
from selfcal.cli.main import main
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot

DATA = Path(__file__).resolve().parents[1] / "data"
SIGMA_MM, SIGMA_DEG = 0.05, 0.01


def _pose_file(path: Path, case, m: int, seed: int) -> np.ndarray:
    """``m`` noisy poses of ``case`` (SIGMA_MM per coordinate, SIGMA_DEG per rotation axis),
    quaternions scalar last; returns the joints (rad)."""
    q = case.configurations(m, seed)
    xyz, R = measure(case, q, SIGMA_MM / 1e3, seed, poses=True)
    noise = np.random.default_rng(seed + 100).normal(0.0, np.radians(SIGMA_DEG), (m, 3))
    quat = Rotation.from_matrix(Rotation.from_rotvec(noise).as_matrix() @ R).as_quat()
    rows = np.column_stack([np.degrees(q), xyz * 1e3, quat])
    header = ",".join(
        [f"j{i + 1}" for i in range(q.shape[1])] + "x_mm y_mm z_mm qx qy qz qw".split()
    )
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.9f")
    return q


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_a_two_axis_positioner_with_a_pose_sensor_reaches_the_noise_floor(tmp_path, capsys):
    robot = DATA / "positioner2.toml"
    case = make_case(load_robot(robot), seed=3)
    _pose_file(tmp_path / "train.csv", case, 30, 3)
    q_test = _pose_file(tmp_path / "test.csv", case, 200, 4)
    out = tmp_path / "cal"
    code, text, err = _run(capsys, "identify", tmp_path / "train.csv", "--robot", robot,
                           "--joint-units", "deg", "--out", out, "--sigma-mm", SIGMA_MM,
                           "--sigma-deg", SIGMA_DEG)  # fmt: skip
    assert code == 0, err
    assert "over 30 poses" in text and "rank 14/14" in text
    doc = json.loads((out / "calibration.json").read_text())
    fit, nominal = doc["fit"], doc["nominal"]
    # the nominal's fit beside the calibrated one, on the terminal and in the file
    assert f"nominal fit RMS {nominal['rms_mm']:.4f} mm, {nominal['rms_deg']:.4f} deg" in text
    # measured: calibrated 0.0909 mm, 0.0169 deg; nominal 0.248 mm, 0.110 deg
    assert fit["rms_mm"] < nominal["rms_mm"] / 2 and fit["rms_deg"] < nominal["rms_deg"] / 4

    target = tmp_path / "predicted.csv"
    code, _, err = _run(capsys, "predict", out, "--measurements", tmp_path / "test.csv",
                        "--joint-units", "deg", "--out", target)  # fmt: skip
    assert code == 0, err
    header = target.read_text().splitlines()[0].split(",")
    assert header == ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz", "error_mm",
                      "nominal_error_mm", "error_deg", "nominal_error_deg"]  # fmt: skip
    table = np.loadtxt(target, delimiter=",", skiprows=1)
    rms = np.sqrt(np.mean(table[:, 7:] ** 2, axis=0))
    assert f"calibrated {rms[0]:.4f} mm, {rms[2]:.4f} deg, nominal {rms[1]:.4f} mm" in err
    # the noise floor of a held-out error: the measurement's own noise, sqrt(3) sigma (0.0866 mm,
    # 0.0173 deg); measured 0.0932 mm (1.08x) and 0.0180 deg (1.04x); the nominal 0.253 mm,
    # 0.113 deg
    floor_mm, floor_deg = np.sqrt(3) * SIGMA_MM, np.sqrt(3) * SIGMA_DEG
    assert rms[0] < 1.15 * floor_mm and rms[2] < 1.1 * floor_deg
    assert rms[1] > 2 * rms[0] and rms[3] > 4 * rms[2]
    # the predicted orientation is the true tool frame's (the noise-free truth, not the data)
    T_true = fk_tool(case.true, q_test)
    quat = table[:, [4, 5, 6, 3]]
    angle = Rotation.from_matrix(T_true[:, :3, :3]).inv() * Rotation.from_quat(quat)
    assert np.degrees(angle.magnitude()).max() < 0.02  # measured max 0.0074 deg


def test_a_seven_axis_arm_through_identify(tmp_path, capsys):
    """Positions of a 7-axis arm: 31 of its 34 MCPC parameters (all but the tool orientation)
    identified; the fit is printed beside the fair nominal's, and predictions are as good as
    those of the 6-axis arms (model error ~ sigma sqrt(p / N))."""
    robot = DATA / "arm7.toml"
    case = make_case(load_robot(robot), seed=5)
    q = case.configurations(60, 5)
    xyz, _ = measure(case, q, 1e-4, 5)
    header = ",".join([f"j{i + 1}" for i in range(7)] + ["x_mm", "y_mm", "z_mm"])
    rows = np.column_stack([np.degrees(q), xyz * 1e3])
    np.savetxt(tmp_path / "m.csv", rows, delimiter=",", header=header, comments="", fmt="%.9f")
    out = tmp_path / "cal"
    code, text, err = _run(capsys, "identify", tmp_path / "m.csv", "--robot", robot,
                           "--joint-units", "deg", "--out", out)  # fmt: skip
    assert code == 0, err
    assert "over 60 positions" in text and "rank 31/34" in text
    doc = json.loads((out / "calibration.json").read_text())
    assert f"nominal fit RMS {doc['nominal']['rms_mm']:.4f} mm (" in text
    # measured: fit 0.141 mm, nominal 2.26 mm
    assert doc["fit"]["rms_mm"] < doc["nominal"]["rms_mm"] / 5
    q_new = case.configurations(50, 6)
    np.savetxt(tmp_path / "j.csv", np.degrees(q_new), delimiter=",", fmt="%.9f")
    code, text, err = _run(capsys, "predict", out, "--joints", tmp_path / "j.csv",
                           "--joint-units", "deg")  # fmt: skip
    assert code == 0, err
    assert text.splitlines()[0] == "x_mm,y_mm,z_mm"  # positions: no orientation identified
    pred = np.loadtxt(text.splitlines()[1:], delimiter=",")
    err_mm = np.linalg.norm(pred - fk_tool(case.true, q_new)[:, :3, 3] * 1e3, axis=1)
    assert err_mm.max() < 0.4  # measured max 0.144 mm


def test_three_poses_of_the_positioner_still_beat_the_nominal(tmp_path, capsys):
    """3 poses (18 equations for 14 parameters): the start comes from the poses in closed form
    (before: from the positions, which 3 rows cannot place; calibrated and nominal both ended
    453 mm off on held-out poses)."""
    robot = DATA / "positioner2.toml"
    case = make_case(load_robot(robot), seed=3)
    _pose_file(tmp_path / "train.csv", case, 3, 3)
    _pose_file(tmp_path / "test.csv", case, 200, 4)
    out = tmp_path / "cal"
    code, _, err = _run(capsys, "identify", tmp_path / "train.csv", "--robot", robot,
                        "--joint-units", "deg", "--out", out, "--sigma-mm", SIGMA_MM,
                        "--sigma-deg", SIGMA_DEG)  # fmt: skip
    assert code == 0, err
    target = tmp_path / "predicted.csv"
    code, _, err = _run(capsys, "predict", out, "--measurements", tmp_path / "test.csv",
                        "--joint-units", "deg", "--out", target)  # fmt: skip
    assert code == 0, err
    rms = np.sqrt(np.mean(np.loadtxt(target, delimiter=",", skiprows=1)[:, 7:] ** 2, axis=0))
    # measured: calibrated 0.226 mm, 0.0175 deg; nominal 0.419 mm, 0.135 deg
    assert rms[0] < 0.7 and rms[2] < 0.05
    assert rms[0] < rms[1] and rms[2] < rms[3] / 3
    assert "the calibration does not predict better" not in err


def test_a_small_set_is_cross_validated_against_the_nominal(tmp_path, capsys):
    """8 poses: identify leaves each configuration out in turn (8 folds) and prints both
    predictions' RMS, recorded in calibration.json (measured: calibrated 0.118 mm, 0.024 deg;
    nominal 0.335 mm, 0.126 deg)."""
    robot = DATA / "positioner2.toml"
    _pose_file(tmp_path / "train.csv", make_case(load_robot(robot), seed=3), 8, 3)
    out = tmp_path / "cal"
    code, text, err = _run(capsys, "identify", tmp_path / "train.csv", "--robot", robot,
                           "--joint-units", "deg", "--out", out, "--sigma-mm", SIGMA_MM,
                           "--sigma-deg", SIGMA_DEG)  # fmt: skip
    assert code == 0, err
    cv = json.loads((out / "calibration.json").read_text())["fit"]["cross_validation"]
    assert cv["rows"] == 8 and cv["folds"] == 8 and cv["configurations"] == 8 and cv["supported"]
    line = (f"cross-validated over 8 rows (8 configurations in 8 folds): held-out RMS calibrated "
            f"{cv['rms_mm']:.4f} mm, {cv['rms_deg']:.4f} deg; fair nominal "
            f"{cv['nominal_rms_mm']:.4f} mm, {cv['nominal_rms_deg']:.4f} deg\n")  # fmt: skip
    assert line in text and "do not support" not in err and "NO GAIN" not in text
    code, text, err = _run(capsys, "identify", tmp_path / "train.csv", "--robot", robot,
                           "--joint-units", "deg", "--out", tmp_path / "again", "--sigma-mm",
                           SIGMA_MM, "--sigma-deg", SIGMA_DEG, "--json")  # fmt: skip
    assert code == 0, err
    assert json.loads(text)["cross_validation"] == cv  # --json carries the check too
    assert cv["rms_mm"] < cv["nominal_rms_mm"] / 2 and cv["rms_deg"] < cv["nominal_rms_deg"] / 3
