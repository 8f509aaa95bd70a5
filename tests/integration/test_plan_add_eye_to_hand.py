"""`selfcal plan --add` to an eye-to-hand dataset (the camera still, the board on the flange):
through the command line on a small analytic dataset of one arm configuration, whose
calibration.json holds the simulated truth's chain with the placement alone identified (what a
calibration of one configuration keeps), so the cell the planner reads out of it is known; and
the refusal of a calibration of two cameras."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.plan.add import HALVE_MORE
from selfcal.cli.main import main
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.io.plan_files import read_plan
from selfcal.io.truth import read_truth
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose

FRAMES = 6


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """(folder, truth, the calibration written): :data:`FRAMES` wrist orientations of one arm
    configuration of the benchmark's still camera cell, acquired analytically."""
    from selfcal.benchmarks.plan.add import _write, still_cell
    from selfcal.calibration.board.nominal_fit import placement_indices
    from selfcal.config.scenario import load_scenario
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.plan_files import joints_csv
    from selfcal.io.target_toml import load_target, target_document
    from selfcal.kinematics.mcpc import param_names
    from selfcal.pipeline.run import run_acquire
    from selfcal.sim.static_camera import plan_static_postures

    tmp = tmp_path_factory.mktemp("add-e2h")
    setup, cell, target, pose = still_cell()
    q = plan_static_postures(cell, 1, FRAMES, seed=1)
    write_text_atomic(tmp / "joints.csv", joints_csv(q, setup.robot.edge_unit))
    run_acquire(load_scenario(_write(tmp, setup, target, pose, "joints.csv", 1)), tmp / "ds",
                quiet=True)  # fmt: skip
    truth = read_truth(tmp / "ds/truth.json")
    assert truth.board is not None
    chain = truth.true_model.with_base(inv_pose(np.asarray(truth.board["T_world_cam"])))
    n = chain.n
    cal = BoardCalibrationResult(
        robot_model="ur5e", target=target_document(load_target(target)),
        camera_names=("cam0",), cameras=(truth.intrinsics_left,), camera_std=({},), model=chain,
        nominal_model=chain, reprojection_rms_px=0.5, frames=FRAMES, frames_used=FRAMES,
        setup="eye-to-hand", selection={"identified": param_names(placement_indices(n))},
    )  # fmt: skip
    write_board_calibration(tmp / "ds/calibration.json", cal)
    return tmp / "ds", truth, cal


@pytest.mark.slow  # plan --add with its forecast and figure: ~4 CPU s
def test_add_plans_for_an_eye_to_hand_dataset(dataset, tmp_path, capsys, monkeypatch):
    import selfcal.calibration.board.plan.spread as spread
    from selfcal.calibration.board.plan.views import PlanSetup, board_views_ok
    from selfcal.config.scenario import load_scenario
    from selfcal.io.tracker import read_joint_rows

    monkeypatch.setattr(spread, "DRAWS", 20)  # the forecast's draws: their count is not tested
    root, truth, cal = dataset
    out = tmp_path / "add"
    argv = ["plan", "--add", "2", str(root), "--candidates", "30", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    line = capsys.readouterr().out
    assert line.startswith(f"add 2 postures to {root} ({FRAMES} frames)")
    for name in ("joints.csv", "trajectory.yaml", "plan.json", "plan.png", "scenario.toml",
                 "replay.csv"):  # fmt: skip
        assert (out / name).is_file(), name
    doc = read_plan(out / "plan.json")
    assert doc["kind"] == "add" and doc["mount"] == "eye-to-hand"
    assert "board_pose_mm_deg" not in doc
    # the cell read out of calibration.json is the truth's: the camera where the simulator put it
    T_bc = np.asarray(truth.board["T_world_cam"])  # the camera -> the world, the base
    s = load_scenario(out / "scenario.toml")
    assert s.camera.setup == "eye-to-hand" and s.trajectory.joints == "replay.csv"
    # the replay simulates the corner noise the forecast assumed (plan.json's, whatever its source)
    assert s.noise.pixel_sigma == pytest.approx(doc["pixel_sigma"]["px"], rel=1e-5)
    assert np.allclose(s.camera.pose, doc["camera_pose_mm_deg"], atol=1e-5)
    # within the arm's deviation (1 mm) of the first link: the chain's base is the truth's
    assert np.allclose(np.asarray(s.camera.pose[:3]) / 1000.0, T_bc[:3, 3], atol=2e-3)
    robot = load_robot("ur5e")
    q = read_joint_rows(out / "joints.csv", robot, "deg").q
    assert q.shape == (2, 6) and np.allclose(np.degrees(q), doc["joints_deg"], atol=1e-6)
    assert read_joint_rows(out / "replay.csv", robot, "deg").q.shape == (FRAMES + 2, 6)
    # the added postures show the whole board to the still camera, on the eye-to-hand rule
    T_fb = np.asarray(truth.board["T_flange_board"])
    cell = PlanSetup.eye_to_hand_setup(robot, cal.cameras[0], _board(root), T_bc, T_fb)
    assert board_views_ok(cell, cell.T_cam_board(q)).all()
    # one configuration keeps the placement alone: the calibration before is the fair nominal,
    # and its prediction (the kept parameters' route) is the fair nominal's (the reference's)
    # (counted beyond the placement, as calibrate's line counts them: 0, was 12 with it)
    assert doc["kinematic_parameters_before"] == 0 <= doc["kinematic_parameters_after"]
    fair = doc["nominal_before"]["fair_nominal_tool_rms_mm"]
    assert doc["predicted_before_tool_rms_mm"] == pytest.approx(fair, abs=2e-4)
    assert doc["nominal"]["drawn_not_a_reference"] is None  # no camera rides on the flange
    # how many postures are predicted to halve the error: the fewest of those tried, by the
    # medians of the forecast's draws (the sixth line's, the same draws), not the first line
    drawn = doc["forecast_draws"]
    halved = doc["halved_with"]
    assert halved["median_before_mm"] == drawn["before"]["median_mm"]
    half = halved["median_before_mm"] / 2.0
    short = line.splitlines()[-1].startswith("not predicted to halve the error with 2 added")
    assert 2 <= halved["tried_up_to"] <= 2 + HALVE_MORE
    if halved["count"] is None:
        assert drawn["after"]["median_mm"] > half and halved["tried_up_to"] == 2 + HALVE_MORE
        assert short and f"nor with any count up to {2 + HALVE_MORE}" in line
    else:
        assert halved["count"] == halved["tried_up_to"]
        assert halved["median_after_mm"] <= half + 1e-4
        assert (halved["count"] == 2) == (drawn["after"]["median_mm"] <= half) != short
        if halved["count"] == 2:
            assert halved["median_after_mm"] == drawn["after"]["median_mm"]
        if short:  # the command that plans them
            assert line.rstrip().endswith(f"selfcal plan --add {halved['count']} {root}")


def _board(root):
    from selfcal.calibration.board.dataset import dataset_board
    from selfcal.io.dataset import Dataset

    return dataset_board(Dataset.open(root))


def test_add_refuses_a_calibration_of_two_cameras(tmp_path, capsys):
    """Refused from calibration.json alone, before the dataset is read (the chain and cameras
    are placeholders: nothing is planned)."""
    from selfcal.camera import Pinhole
    from selfcal.io.target_toml import load_target, target_document
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import models_dir

    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    T = np.stack([np.eye(4), np.eye(4)])
    T[1, 0, 3] = 0.1
    cal = BoardCalibrationResult(
        robot_model=robot.name, target=target_document(load_target(models_dir() / "targets/charuco.toml")),
        camera_names=("left", "right"), cameras=(cam, cam), camera_std=({}, {}),
        model=nominal_mcpc(robot), nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.1,
        frames=8, frames_used=8, setup="eye-to-hand", T_first_cam=T,
    )  # fmt: skip
    write_board_calibration(tmp_path / "calibration.json", cal)
    assert main(["plan", "--add", "2", str(tmp_path), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert "--add plans for one camera (either mount) only" in err
    assert "eye-to-hand with 2 cameras (left, right)" in err and "into a dataset of its own" in err
    assert not (tmp_path / "p").exists()
