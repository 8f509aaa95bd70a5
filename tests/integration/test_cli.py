"""The command line: JSON outputs, and bad input exits non-zero naming the problem."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from selfcal.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_fk_prints_table_ii_row_one(capsys):
    code, out, _ = run(capsys, "fk", "--robot", "er4u-paper", "--joints", "38.15,-30,45,-63.54,0")
    assert code == 0
    doc = json.loads(out)
    np.testing.assert_allclose(doc["xyz_mm"], [315.60, 247.90, 190.30], atol=0.1)
    assert abs(doc["pitch_deg"] - (-138.54)) < 1e-3 and abs(doc["roll_deg"]) < 1e-9


def test_ik_round_trips_through_fk(capsys):
    code, out, _ = run(
        capsys,
        "ik",
        "--robot",
        "er4u-paper",
        "--xyz",
        "310.4,243.8,197.7",
        "--pitch",
        "-138.54",
        "--roll",
        "0",
    )
    assert code == 0
    q = json.loads(out)["joints_deg"]
    code, out, _ = run(capsys, "fk", "--joints", ",".join(f"{v:.9f}" for v in q))
    doc = json.loads(out)
    np.testing.assert_allclose(doc["xyz_mm"], [310.4, 243.8, 197.7], atol=1e-4)
    assert abs(doc["pitch_deg"] + 138.54) < 1e-3


def test_negative_numbers_work_as_typed(capsys):
    """A comma list that starts with a minus is a value (argparse took it for an option)."""
    from selfcal.cli.main import build_parser
    from selfcal.console.common import SelfcalParser, leaf_parsers

    code, typed, err = run(capsys, "fk", "--joints", "-10,20,30,0,0")
    assert code == 0, err
    assert run(capsys, "fk", "--joints=-10,20,30,0,0")[1] == typed
    xyz = ",".join(f"{v:.6f}" for v in json.loads(typed)["xyz_mm"])
    code, out, err = run(
        capsys, "ik", "--xyz", xyz, "--pitch", "-40", "--reference", "-10,20,30,0,0"
    )
    assert code == 0, err
    np.testing.assert_allclose(json.loads(out)["joints_deg"], [-10, 20, 30, 0, 0], atol=1e-4)
    assert all(isinstance(p, SelfcalParser) for p in leaf_parsers(build_parser()))


def test_ik_unreachable_exits_nonzero(capsys):
    code, out, err = run(capsys, "ik", "--xyz", "2000,0,0", "--pitch", "0")
    assert code != 0 and out == ""
    assert "unreachable" in err and "mm" in err


@pytest.mark.parametrize(
    "argv, words",
    [
        (
            ["fk", "--robot", "er9", "--joints", "0,0,0,0,0"],
            ["unknown robot model 'er9'", "er4u-paper"],
        ),
        (["fk", "--joints", "0,zero,0,0,0"], ["--joints", "comma-separated numbers"]),
        (["fk", "--joints", "0,0,0"], ["expected 5 numbers"]),
        (
            ["fk", "--joints", "0,140,0,0,0"],
            ["joint 2 (shoulder)", "140.000 deg", "[-35.00, 130.00]"],
        ),
        (["ik", "--xyz", "1,2", "--pitch", "0"], ["--xyz", "expected 3 numbers"]),
    ],
)
def test_bad_input_names_the_problem(capsys, argv, words):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    for w in words:
        assert w in err


@pytest.mark.render
def test_render_writes_the_stereo_pair(capsys, tmp_path):
    import cv2

    code, out, _ = run(
        capsys, "render", "--joints", "38.15,-30,45,-63.54,0", "--out", str(tmp_path)
    )
    assert code == 0
    paths = json.loads(out)
    for key in ("left", "right"):
        img = cv2.imread(paths[key])
        assert img.shape == (480, 640, 3) and img.std() > 10


@pytest.mark.render
def test_render_of_a_one_camera_scenario_writes_its_one_camera(capsys, tmp_path):
    """A scenario of one camera ([camera] count = 1) rendered a right.png too: the
    simulator's pair, from a second camera the scenario does not have."""
    (tmp_path / "mono.toml").write_text("[camera]\ncount = 1\n")
    out_dir = tmp_path / "r"
    code, out, _ = run(capsys, "render", str(tmp_path / "mono.toml"), "--joints",
                       "38.15,-30,45,-63.54,0", "--out", str(out_dir))  # fmt: skip
    assert code == 0
    assert list(json.loads(out)) == ["left"]
    assert sorted(p.name for p in out_dir.iterdir()) == ["left.png"]


def test_help_lists_scenario_keys(capsys):
    assert main(["run", "--help"]) == 0
    out = capsys.readouterr().out
    for key in ("scale_length_mm", "pixel_sigma", "backend", "baseline_mm", "[validation]"):
        assert key in out


def test_fk_ik_round_trip_of_a_six_axis_arm(capsys):
    """UR5e: fk prints the orientation as rpy and quaternion; ik takes either back."""
    q = [10.0, -95.0, 100.0, -95.0, -85.0, 20.0]
    code, out, _ = run(capsys, "fk", "--robot", "ur5e", "--joints", ",".join(map(str, q)))
    assert code == 0
    doc = json.loads(out)
    assert "pitch_deg" not in doc  # the ER convention only for ER-type arms
    xyz = ",".join(f"{v:.6f}" for v in doc["xyz_mm"])
    for opt, val in (("--rpy-deg", doc["rpy_deg"]), ("--quat", doc["quat_wxyz"])):
        vals = ",".join(f"{v:.9f}" for v in val)
        # "--key=value": the values may start with a minus sign
        code, out, _ = run(capsys, "ik", "--robot", "ur5e", f"--xyz={xyz}", f"{opt}={vals}")
        assert code == 0, opt
        res = json.loads(out)
        assert res["solver"] == "numeric"
        # fk rounds xyz to 1e-4 mm and rpy to 1e-6 deg: the posture comes back to ~1e-5 deg
        np.testing.assert_allclose(res["joints_deg"], q, atol=1e-4)


def test_ik_pitch_roll_is_refused_for_a_six_axis_arm(capsys):
    code, out, err = run(capsys, "ik", "--robot", "ur5e", "--xyz=-400,-133,400", "--pitch", "0")
    assert code == 2 and out == ""
    assert "--rpy-deg" in err and "ur5e" in err


def test_ik_needs_exactly_one_orientation(capsys):
    code, _, err = run(capsys, "ik", "--xyz", "300,0,200", "--pitch", "0", "--rpy-deg", "0,0,0")
    assert code == 2 and "exactly one tool orientation" in err


def test_ik_reference_and_position_only_for_a_six_axis_arm(capsys):
    """--reference picks the solution branch nearest the current posture; --position-only frees
    the orientation."""
    q = [30.0, -60.0, -100.0, -110.0, 80.0, 40.0]  # elbow on the other side of home's
    code, out, _ = run(capsys, "fk", "--robot", "ur5e", "--joints", ",".join(map(str, q)))
    doc = json.loads(out)
    xyz = ",".join(f"{v:.6f}" for v in doc["xyz_mm"])
    rpy = ",".join(f"{v:.9f}" for v in doc["rpy_deg"])
    ref = ",".join(str(v + 2.0) for v in q)
    argv = ["ik", "--robot", "ur5e", f"--xyz={xyz}", f"--rpy-deg={rpy}", f"--reference={ref}"]
    code, out, _ = run(capsys, *argv)
    assert code == 0
    np.testing.assert_allclose(json.loads(out)["joints_deg"], q, atol=1e-4)
    code, out, _ = run(capsys, "ik", "--robot", "ur5e", f"--xyz={xyz}", "--position-only")
    assert code == 0
    q2 = json.loads(out)["joints_deg"]
    code, out, _ = run(capsys, "fk", "--robot", "ur5e", "--joints", ",".join(map(str, q2)))
    np.testing.assert_allclose(json.loads(out)["xyz_mm"], doc["xyz_mm"], atol=1e-3)


def test_fk_ik_of_an_arm_on_a_linear_track_take_the_track_in_mm(capsys, tmp_path):
    """A UR5e on a 2 m vertical track (prismatic joint 1, 7 joints): ``--joints`` and ``joints_deg`` hold
    the track in mm (before: read as degrees, 1500 "deg" = 26 m, out of range); fk and ik
    round-trip, and moving the track moves the tool by as much."""
    text = (ROOT / "models/universal_robots_ur5e/ur5e.toml").read_text()
    track = (
        '[[joint]]\nname = "track"\ntype = "prismatic"\nalpha_deg = 0.0\na_mm = 0.0\n'
        "d_mm = 0.0\nrange_mm = [0.0, 2000.0]\n\n"
    )
    text = text.replace("[[joint]]", track + "[[joint]]", 1)
    text = text.replace("home_deg = [", "home_deg = [500.0, ")
    text = text.split("[encoder]")[0]  # per-joint tables of 6 values: not for 7 joints
    robot = tmp_path / "ur5e-track.toml"
    robot.write_text(text)
    q = [1500.0, 10.0, -95.0, 100.0, -95.0, -85.0, 20.0]
    docs = []
    for track_mm in (1500.0, 1000.0):
        joints = ",".join(map(str, [track_mm] + q[1:]))
        code, out, err = run(capsys, "fk", "--robot", str(robot), "--joints", joints)
        assert code == 0, err
        docs.append(json.loads(out))
    assert docs[0]["joints_deg"] == q
    np.testing.assert_allclose(
        np.subtract(docs[0]["xyz_mm"], docs[1]["xyz_mm"]), [0, 0, 500], atol=1e-3
    )
    xyz = ",".join(f"{v:.6f}" for v in docs[0]["xyz_mm"])
    quat = ",".join(f"{v:.9f}" for v in docs[0]["quat_wxyz"])
    ref = ",".join(map(str, [1450.0] + q[1:]))
    code, out, err = run(
        capsys, "ik", "--robot", str(robot), f"--xyz={xyz}", f"--quat={quat}", "--reference", ref
    )
    assert code == 0, err
    # 7 joints for a 6-D pose: a solution near the reference that gives the pose back
    sol = json.loads(out)["joints_deg"]
    assert 1000.0 < sol[0] < 2000.0
    code, out, err = run(capsys, "fk", "--robot", str(robot), "--joints", ",".join(map(str, sol)))
    back = json.loads(out)
    np.testing.assert_allclose(back["xyz_mm"], docs[0]["xyz_mm"], atol=1e-3)
    np.testing.assert_allclose(
        np.abs(np.dot(back["quat_wxyz"], docs[0]["quat_wxyz"])), 1.0, atol=1e-9
    )


@pytest.mark.render
def test_render_takes_a_robot_file_of_seven_joints(capsys, tmp_path):
    """``--robot FILE`` outside models/ (before: "unknown robot model 'arm7'")."""
    import cv2

    robot = ROOT / "tests" / "data" / "arm7.toml"
    joints = "0,-30,0,-130,0,100,45"
    code, out, err = run(capsys, "render", "--robot", str(robot), "--joints", joints,
                         "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    img = cv2.imread(json.loads(out)["left"])
    assert img.shape == (480, 640, 3) and img.std() > 10


def test_the_console_script_runs_main_and_leaves_the_heap_frozen(capsys, monkeypatch):
    """``selfcal`` (the console script, pyproject.toml) is ``script``: main's exit code, and
    the objects left frozen (gc.freeze) so that the interpreter's exit does not walk them
    (issue 32: 0.12 s of CPU at the end of a run)."""
    import gc
    import importlib.metadata
    import sys

    from selfcal.cli.main import script

    (ep,) = importlib.metadata.entry_points(group="console_scripts", name="selfcal")
    assert ep.value == "selfcal.cli.main:script"
    monkeypatch.setattr(sys, "argv", ["selfcal", "fk", "--joints", "0,0,0,0,0"])
    before = gc.get_freeze_count()
    try:
        assert script() == 0
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()  # this test process keeps collecting
    assert json.loads(capsys.readouterr().out)["model"]
