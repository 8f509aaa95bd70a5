"""`selfcal plan --check K CALIBRATION` (issue #29): the postures of a drift check chosen by the
check's stated power, through the command line on the shared small board calibration
(conftest.py ``mono_charuco_15``: the ER-4u eye-in-hand, analytic, 15 postures), its errors,
and the cell the choice reads out of the calibration (the camera's mount the robot file's way
round); eye-to-hand in the slow tier."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.mounts import mounts
from selfcal.calibration.board.plan.add_cell import calibrated_cell
from selfcal.calibration.board.plan.candidates import candidate_pool
from selfcal.calibration.drift.choose import CHECK_CORNERS, candidate_views, check_cell
from selfcal.calibration.drift.images import calibration_error_model
from selfcal.calibration.drift.power import shift_power
from selfcal.cli.main import main
from selfcal.io.board_calibration import read_board_calibration
from selfcal.io.plan_files import read_plan
from selfcal.io.target_toml import parse_target
from selfcal.io.tracker import read_joint_rows
from selfcal.robot.definition import load_robot


def _in_image(cal, q: np.ndarray) -> list[int]:
    """How many board features lie in front of the calibrated camera and inside its image at
    each posture of ``q`` (m, n) rad, by the calibration's own chain (what the check predicts)."""
    from selfcal.calibration.board.misfit import board_view
    from selfcal.kinematics.forward import fk_tool

    _, X = parse_target(cal.target, "target").layout()
    cam = cal.cameras[0]
    out = []
    for T in fk_tool(cal.model, q):
        x, uv, _, _ = board_view(cam, T, X, cal.eye_to_hand)
        out.append(
            int(np.sum((x[:, 2] > 0) & np.all((uv >= 0) & (uv < [cam.width, cam.height]), axis=1)))
        )
    return out


def _sees_the_board(cal, q: np.ndarray) -> bool:
    """Every board feature in front of the calibrated camera and inside its image at each
    posture of ``q`` (m, n) rad, by the calibration's own chain."""
    n = len(parse_target(cal.target, "target").layout()[1])
    return all(k == n for k in _in_image(cal, q))


@pytest.mark.slow  # a calibration of its own: ~3 CPU s
def test_the_camera_mount_is_read_out_the_robot_files_way_round(tmp_path):
    """The ER-4u's board calibration at 0.2 px (mono-charuco, analytic, 12 postures) read its
    camera out turned half about the flange's z axis (179.6 deg and 90 mm from the robot
    file's mount: the last joint frame's x axis, by which the way round was chosen, came out
    across the nominal's, dot product -0.007), so the cell of `plan --check` and `plan --add`
    saw the board behind the camera (every candidate's features at negative depth by the
    calibration's chain). The scenario moves the mount by at most 1 mm and 0.5 deg. (The
    shared 15-posture calibration at 0.5 px came out the right way round before too.)"""
    from selfcal.config.scenario import load_scenario, scenarios_dir
    from selfcal.pipeline.run import run_all

    out = tmp_path / "cal"
    s = load_scenario(scenarios_dir() / "mono-charuco.toml",
                      {"noise": {"render": False, "pixel_sigma": 0.2}, "trajectory": {"poses": 12}})  # fmt: skip
    run_all(s, out, quiet=True, figures=False)
    cal = read_board_calibration(out)
    robot = load_robot(cal.robot_model)
    T = mounts(cal.model, robot, eye_to_hand=False)[0].T
    turn = Rotation.from_matrix(robot.T_flange_cam[:3, :3].T @ T[:3, :3]).magnitude()
    assert np.degrees(turn) < 2.0
    assert np.linalg.norm(T[:3, 3] - robot.T_flange_cam[:3, 3]) < 5e-3
    setup, _ = calibrated_cell(cal, robot, cal.cameras[0], parse_target(cal.target, "t"),
                               np.zeros((0, 6)))  # fmt: skip
    pool, _ = candidate_pool(setup, 10, seed=1)
    assert _sees_the_board(cal, pool)  # the cell's candidates, by the calibration's chain


def test_plan_check_round_trip(mono_charuco_15, tmp_path, capsys):
    """3 postures of 10 candidates: joints.csv reads back as plan.json's postures, which see
    at least CHECK_CORNERS of the board's features by the calibration's chain (part of the board
    may lie outside the image); the stated power of the chosen set is that of the features
    those views are expected to detect (recomputed from the postures), and above the first 3 candidates' (the random set) stated
    beside it; the line says both."""
    out, _ = mono_charuco_15
    plan = tmp_path / "plan"
    assert main(["plan", "--check", "3", str(out), "--candidates", "10", "--out", str(plan),
                 "--json"]) == 0  # fmt: skip
    doc = json.loads(capsys.readouterr().out)
    assert doc == read_plan(plan / "plan.json", kinds=("check",))
    assert doc["kind"] == "check" and doc["count"] == 3 and doc["candidates"] == 10
    cal = read_board_calibration(out)
    q = np.radians(doc["joints_deg"])
    rows = read_joint_rows(plan / "joints.csv", load_robot(cal.robot_model), "deg")
    assert np.allclose(rows.q, q, atol=1e-7)
    assert (plan / "trajectory.yaml").is_file()
    assert min(_in_image(cal, q)) >= CHECK_CORNERS
    chosen, random = doc["power"], doc["random_power"]
    assert chosen["size_mm"] == 0.2 and chosen["mount"] == "camera" and chosen["images"] == 3
    assert chosen["power"] > random["power"]
    # the power stated is that of the features each posture is expected to detect (recomputed:
    # the plan.json round trip, not the power `selfcal check` states from detected corners)
    em = calibration_error_model(cal, "calibration.json")
    from selfcal.calibration.drift.covariance import estimate_covariance

    setup = check_cell(
        calibrated_cell(
            cal,
            load_robot(cal.robot_model),
            cal.cameras[0],
            parse_target(cal.target, "t"),
            np.zeros((0, 6)),
        )[0]
    )
    views = candidate_views(cal, em, setup, q)
    again = shift_power(estimate_covariance(cal, em), views, eye_to_hand=False, alpha=0.01,
                        search=False)  # fmt: skip
    assert again.power == pytest.approx(chosen["power"])
    line = doc["line"]
    assert "these 3 postures find a 0.2 mm move of the camera's mount" in line
    assert f"with {chosen['power']:.0%} power (random 3: {random['power']:.0%}" in line


def test_plan_check_errors_name_the_file_and_the_option(mono_charuco_15, tmp_path, capsys):
    """A tracker calibration is refused saying what is supported; a folder without a
    calibration, a field calibration and a board calibration without its accuracy block are
    named; options the calibration gives are refused by name."""
    out, _ = mono_charuco_15
    plan = str(tmp_path / "plan")
    tracker = tmp_path / "tracker.json"
    tracker.write_text(json.dumps({"format": "scorbot-selfcal-tracker-calibration"}))
    assert main(["plan", "--check", "5", str(tracker), "--out", plan]) == 2
    err = capsys.readouterr().err
    assert str(tracker) in err and "tracker calibration" in err and "board calibration" in err
    assert main(["plan", "--check", "5", str(tmp_path / "nothing"), "--out", plan]) == 2
    assert f"{tmp_path / 'nothing'} not found" in capsys.readouterr().err
    field = tmp_path / "field"
    field.mkdir()
    (field / "calibration.json").write_text(json.dumps({"format": "scorbot-selfcal-calibration"}))
    assert main(["plan", "--check", "5", str(field), "--out", plan]) == 2
    err = capsys.readouterr().err
    assert str(field / "calibration.json") in err and "not a board calibration" in err
    old = tmp_path / "old"
    shutil.copytree(out, old, ignore=shutil.ignore_patterns("frames"))
    doc = json.loads((old / "calibration.json").read_text())
    del doc["accuracy"]
    (old / "calibration.json").write_text(json.dumps(doc))
    assert main(["plan", "--check", "5", str(old), "--out", plan]) == 2
    err = capsys.readouterr().err
    assert str(old / "calibration.json") in err and "no accuracy or bounds block" in err
    for extra in (["--count", "5"], ["--mount", "eye-to-hand"], ["--pixel-sigma", "0.3"]):
        assert main(["plan", "--check", "5", str(out), "--out", plan, *extra]) == 2
        assert f"{extra[0]} would not be used" in capsys.readouterr().err
    assert main(["plan", "--check", "x", str(out), "--out", plan]) == 2
    assert "K must be a whole number" in capsys.readouterr().err
    assert main(["plan", "--check", "5", str(out), "--candidates", "4", "--out", plan]) == 2
    assert "--candidates 4" in capsys.readouterr().err


@pytest.mark.slow  # an eye-to-hand calibration and the choice: ~10 CPU s
def test_plan_check_eye_to_hand(tmp_path, capsys):
    """The still camera's cell (scenarios/eye-to-hand.toml, analytic, 12 postures): the chosen
    postures see at least CHECK_CORNERS of the board's features by the calibration's chain, and their stated
    power against a 0.2 mm move of the board's mount is above the random set's."""
    from selfcal.config.scenario import load_scenario, scenarios_dir
    from selfcal.pipeline.run import run_all

    out = tmp_path / "cal"
    s = load_scenario(scenarios_dir() / "eye-to-hand.toml",
                      {"noise": {"render": False, "pixel_sigma": 0.2}, "trajectory": {"poses": 12}})  # fmt: skip
    run_all(s, out, quiet=True, figures=False)
    capsys.readouterr()
    assert main(["plan", "--check", "3", str(out), "--candidates", "10", "--out",
                 str(tmp_path / "plan"), "--json"]) == 0  # fmt: skip
    doc = json.loads(capsys.readouterr().out)
    assert doc["mount"] == "eye-to-hand" and doc["power"]["mount"] == "board"
    assert doc["power"]["power"] > doc["random_power"]["power"]
    assert (
        min(_in_image(read_board_calibration(out), np.radians(doc["joints_deg"]))) >= CHECK_CORNERS
    )


@pytest.mark.slow  # a 30-posture calibration and its checks: ~8 CPU s
def test_the_benchmark_checks_the_commands_postures():
    """``python -m selfcal.benchmarks.drift.choose``'s one calibration: the command's choice
    and the random set, each checked unchanged and shifted; the stated powers are the
    command's (chosen above random), the counts within the checks made (with the joint offset's
    checks), no view misses a corner the command expected."""
    from selfcal.benchmarks.drift.choose import SETS, chosen_checks, table

    got = chosen_checks((0.2, 1, 2, "eye-in-hand", None, 3, 8, True))
    assert got["status"] == "ok", got["status"]
    assert 0.0 <= got["random_power"] < got["chosen_power"] <= 1.0
    for s in SETS:
        assert 0 <= got[f"{s}_tool"] <= 2 and 0 <= got[f"{s}_unchanged"] <= 2
        assert 0 <= got[f"{s}_joint"] + got[f"{s}_joint_cannot_tell"] <= 2  # --joint-offset
        assert got[f"{s}_views_missing_expected"] == 0  # the corners the command expected
    row = {"setup": "eye-in-hand, er4u-paper", "noise_px": 0.2, "calibrations": 1} | got
    assert "| chosen |" in table([row]) and "| random |" in table([row])


def test_a_view_of_part_of_the_board_is_linearised_with_the_features_it_would_detect(
    mono_charuco_15,
):
    """Candidates near the calibration's postures that see part of the board: each view is
    linearised with the features it would detect (expected_features, by the calibration's
    chain), not the whole board's, and the power stated for three of them is below what the
    whole board's features there would give (before, every feature was linearised)."""
    from selfcal.calibration.board.accuracy import board_postures_from_json
    from selfcal.calibration.board.misfit import board_view
    from selfcal.calibration.drift.choose import candidates_near, expected_features
    from selfcal.calibration.drift.covariance import estimate_covariance
    from selfcal.calibration.drift.views import calibration_views
    from selfcal.kinematics.forward import fk_tool

    out, _ = mono_charuco_15
    cal = read_board_calibration(out)
    board = parse_target(cal.target, "t")
    setup = check_cell(calibrated_cell(cal, load_robot(cal.robot_model), cal.cameras[0], board,
                                       np.zeros((0, 6)))[0])  # fmt: skip
    q_cal = board_postures_from_json(cal.accuracy, cal.model.n, "calibration.json")
    q = candidates_near(setup, q_cal, 40, seed=2)
    seen = expected_features(cal, setup, q)
    _, X = board.layout()
    k = seen.sum(axis=1)
    part = np.flatnonzero(k >= CHECK_CORNERS)
    part = part[np.argsort(k[part], kind="stable")]  # the fewest features first
    assert len(part) >= 3 and k[part[2]] < len(X), k
    q = q[part[:3]]
    em = calibration_error_model(cal, "calibration.json")
    views = candidate_views(cal, em, setup, q)
    assert [len(v.r) for v in views] == [2 * k for k in seen[part[:3]].sum(axis=1)]
    T = fk_tool(cal.model, q)
    whole = calibration_views(cal, em, q, [(i, X, board_view(cal.cameras[0], T[i], X, False)[1])
                                           for i in range(len(q))])  # fmt: skip
    C = estimate_covariance(cal, em)
    got, all_of_it = (shift_power(C, v, eye_to_hand=False, alpha=0.01, search=False).power
                      for v in (views, whole))  # fmt: skip
    assert got < all_of_it


@pytest.mark.slow  # 5 rendered images: ~10 CPU s
def test_the_chosen_postures_render_with_the_corners_the_plan_expects(mono_charuco_15, tmp_path,
                                                                      capsys):  # fmt: skip
    """`plan --check 5` on the shared calibration, its postures rendered with MuJoCo on the
    scenario's true arm (the one the calibration's images came from) and detected: every corner
    the plan linearised (expected_features, by the calibration's chain) is detected in every
    image, views of part of the board among them or not."""
    from selfcal.acquisition.backends import make_sim_robot
    from selfcal.calibration.drift.choose import expected_features
    from selfcal.config.scenario import load_scenario, scenarios_dir

    out, _ = mono_charuco_15
    plan = tmp_path / "plan"
    assert main(["plan", "--check", "5", str(out), "--out", str(plan), "--json"]) == 0
    q = np.radians(json.loads(capsys.readouterr().out)["joints_deg"])
    cal = read_board_calibration(out)
    board = parse_target(cal.target, "t")
    setup = check_cell(calibrated_cell(cal, load_robot(cal.robot_model), cal.cameras[0], board,
                                       np.zeros((0, 6)))[0])  # fmt: skip
    expected = expected_features(cal, setup, q)
    ids = board.layout()[0]
    s = load_scenario(scenarios_dir() / "mono-charuco.toml",
                      {"noise": {"render": True}, "trajectory": {"poses": 15}})  # fmt: skip
    with make_sim_robot(s) as sim:
        for i, qi in enumerate(q):
            sim.move_to(np.degrees(qi))
            got = set(board.detect(sim.capture().left).ids.tolist())
            want = set(ids[expected[i]].tolist())
            assert want <= got, (i, sorted(want - got))
    print("features expected per view:", expected.sum(axis=1).tolist())


def test_the_help_and_the_docs_say_the_choices_numbers():
    """`plan --help`'s --check text and docs/tool-accuracy.md give the rule's numbers as the
    code has them."""
    from pathlib import Path

    from selfcal.calibration.drift.choose import CHECK_SPREAD, NEAR_DEG
    from selfcal.cli.plan_check import CHECK_EPILOG

    docs = (Path(__file__).resolve().parents[2] / "docs/tool-accuracy.md").read_text()
    for text in (" ".join(CHECK_EPILOG.split()), " ".join(docs.split())):
        assert f"within {NEAR_DEG:g} deg of the calibration's" in text
        assert f"at least {CHECK_CORNERS} features" in text
        assert {0.25: "a quarter"}[CHECK_SPREAD] + " of the image each way" in text
