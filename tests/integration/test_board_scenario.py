"""A board scenario (``[target] board``, scenarios/mono-charuco.toml) through the simulator and
``selfcal run``: the board lies where truth.json says, and the board route calibrates camera,
hand-eye and kinematics from the rendered images (issue #12's mono + ChArUco acceptance)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.acquisition.backends import make_sim_robot
from selfcal.acquisition.simulator_setup import sim_setup
from selfcal.config.scenario import load_scenario, scenario_board
from selfcal.io.target_toml import parse_target, target_document
from selfcal.pipeline.run import run_all
from selfcal.transforms import inv_pose

MONO_CHARUCO = Path(__file__).resolve().parents[2] / "scenarios" / "mono-charuco.toml"


@pytest.mark.slow  # default tier budget (~90 s): 2-5 s each
def test_the_rendered_board_is_where_truth_json_puts_it():
    """At home the camera looks at the board's centre: the detected corners agree with the
    corners projected from truth.json (its board's target keys and pose, the true camera with
    its lens, the true camera pose). Measured: 69 of 88 corners, 0.051 px RMS,
    mean (-0.0019, +0.0015) px."""
    s = load_scenario(MONO_CHARUCO)
    with make_sim_robot(s, sim_setup(s)) as robot:
        truth = robot.truth()
        frame = robot.truth_frame()
        image = robot.capture().left
    assert truth.board is not None
    board = parse_target(truth.board["target"], "truth.json: board")
    assert truth.board["target"] == target_document(scenario_board(s))
    f = board.detect(image)
    assert len(f) >= 0.5 * board.n_features  # measured 69 of 88 at home
    T = inv_pose(frame["T_world_cam_left"]) @ truth.T_world_board
    X = board.points(f.ids) @ T[:3, :3].T + T[:3, 3]
    e = f.uv - truth.intrinsics_left.project(X)
    rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    print(f"{len(f)} corners, RMS {rms:.3f} px, mean {e.mean(axis=0)}")
    assert rms < 0.15
    assert np.abs(e.mean(axis=0)).max() < 0.008  # ~4x: the mean of 69 has a std of 0.006 px


@pytest.mark.slow
def test_mono_charuco_run_reaches_the_truth(tmp_path):
    """``selfcal run scenarios/mono-charuco.toml`` (the pipeline API): rendered views through the
    issue's lens, board detection, the board calibration and the report against truth.json.
    Measured (seed 1; seeds 2-4 in brackets): every free camera parameter within 1.69 sigma
    (0.96, 1.86, 1.27); tool tip 0.102 mm RMS against 1.579 mm nominal (0.084, 0.203, 0.104 mm);
    camera pose in the board 0.110 mm / 0.049 deg (0.094 .. 0.232 mm, 0.017 .. 0.040 deg);
    hand-eye 0.087 mm / 0.049 deg (0.032 .. 0.151 mm, 0.016 .. 0.041 deg)."""
    s = load_scenario(MONO_CHARUCO)
    rep = run_all(s, tmp_path / "run", quiet=True, figures=False)["report"]
    assert rep["status"] == "ok"
    cam = rep["camera"]
    assert set(cam) == set(s.camera.free)
    for name, c in cam.items():
        assert abs(c["z"]) < 3.0, (name, c)  # the acceptance
    v = rep["validation"]
    tip = v["tool_tip_error_mm"]
    assert tip["calibrated"]["rms"] < 0.3  # measured 0.102
    assert tip["calibrated"]["rms"] < 0.2 * tip["nominal"]["rms"]  # measured 0.064
    pose = v["camera_pose_in_board"]["calibrated"]
    assert pose["position_mm"]["rms"] < 0.35 and pose["rotation_deg"]["rms"] < 0.15
    he = rep["hand_eye"]["calibrated"]
    assert he["position_mm"]["rms"] < 0.3 and he["rotation_deg"]["rms"] < 0.15
    assert he["position_mm"]["rms"] < rep["hand_eye"]["nominal"]["position_mm"]["rms"]
    assert (tmp_path / "run" / "report.md").is_file()


@pytest.mark.slow
def test_stereo_charuco_run_reaches_the_truth(tmp_path):
    """The same scenario with the stereo pair (``camera.count = 2``): the board calibration of
    the rig (every camera its own model, the second's pose in the first's frame) and the robot.
    Measured: every free parameter of both cameras within 2.16 sigma; the right camera's pose
    0.054 mm / 0.019 deg from the truth; tool tip 0.036 mm RMS against 1.579 mm nominal."""
    s = load_scenario(MONO_CHARUCO, overrides={"camera": {"count": 2}})
    rep = run_all(s, tmp_path / "run", quiet=True, figures=False)["report"]
    assert rep["status"] == "ok"
    (name, right), *more = rep["rig"].items()
    assert name == "right" and not more
    for rows in (rep["camera"], right["camera"]):
        assert set(rows) == set(s.camera.free)
        for n, c in rows.items():
            assert abs(c["z"]) < 3.0, (n, c)
    e = right["extrinsics"]
    assert e["position_mm"]["rms"] < 0.16 and e["rotation_deg"]["rms"] < 0.06
    tip = rep["validation"]["tool_tip_error_mm"]
    assert tip["calibrated"]["rms"] < 0.11  # measured 0.036
