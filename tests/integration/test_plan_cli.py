"""`selfcal plan` end to end: its files parse with the readers that use them (the import's joints
reader, YAML, the scenario loader) and `selfcal run` of its scenario sees the board in every
planned posture."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from selfcal.cli.main import main
from selfcal.config.scenario import load_scenario
from selfcal.io.tracker import read_joint_rows
from selfcal.robot.definition import load_robot, models_dir

BOARD = str(models_dir() / "targets/charuco.toml")


def _plan(out, count: int = 6, candidates: int = 60) -> None:
    argv = ["plan", "--robot", "ur5e", "--target", BOARD, "--fov-deg", "60", "--resolution",
            "640x480", "--board-pose", "-472,-133,3", "--count", str(count), "--keep-out",
            "-300,50,0,-100,400,600", "--candidates", str(candidates), "--out", str(out),
            "--quiet"]  # fmt: skip
    assert main(argv) == 0


def test_plan_files_parse(tmp_path, capsys):
    _plan(tmp_path / "plan")
    line = capsys.readouterr().out.strip()
    assert line.startswith("plan of 6 postures: predicted tool-point error")
    robot = load_robot("ur5e")
    doc = json.loads((tmp_path / "plan/plan.json").read_text())
    q = read_joint_rows(tmp_path / "plan/joints.csv", robot, "deg").q
    assert q.shape == (6, 6)
    assert np.allclose(np.degrees(q), doc["joints_deg"], atol=1e-6)
    assert doc["predicted_tool_rms_mm"] <= doc["random_tool_rms_mm"]
    assert f"{doc['predicted_tool_rms_mm']:.3f}" in line
    traj = yaml.safe_load((tmp_path / "plan/trajectory.yaml").read_text())
    assert traj["joint_names"] == list(robot.joint_names)
    pos = np.array([p["positions"] for p in traj["points"]])
    assert np.allclose(pos[::2], q, atol=1e-8) and np.allclose(pos[1::2], q, atol=1e-8)
    t = [
        p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in traj["points"]
    ]
    assert np.all(np.diff(t) > 0)
    s = load_scenario(tmp_path / "plan/scenario.toml")
    assert s.trajectory.kind == "file" and s.camera.count == 1
    assert s.target.board_pose[:3] == [-472.0, -133.0, 3.0]
    with open(tmp_path / "plan/joints.csv") as f:
        assert next(csv.reader(f)) == [f"j{k}" for k in range(1, 7)]


def test_plan_refuses_a_board_no_posture_sees(tmp_path, capsys):
    argv = ["plan", "--robot", "ur5e", "--target", BOARD, "--fov-deg", "60", "--resolution",
            "640x480", "--board-pose", "5000,0,0", "--count", "6", "--out", str(tmp_path / "p")]  # fmt: skip
    assert main(argv) == 2
    assert "sees the whole board" in capsys.readouterr().err


@pytest.mark.slow
def test_run_of_the_plan_sees_the_board_in_every_posture(tmp_path):
    _plan(tmp_path / "plan", count=10, candidates=200)
    assert main(["run", str(tmp_path / "plan/scenario.toml"), "--out", str(tmp_path / "run"),
                 "--quiet"]) == 0  # fmt: skip
    with open(tmp_path / "run/detections.csv") as f:
        rows = list(csv.DictReader(f))
    per_frame = np.bincount([int(r["index"]) for r in rows], minlength=10)
    n_features = 88  # the ChArUco's 11 x 8 inner corners: every one in every planned view
    assert per_frame.tolist() == [n_features] * 10


@pytest.mark.slow
def test_the_docs_plan_line_is_what_the_command_prints(tmp_path, capsys):
    """docs/plan.md shows the line its command prints (the same command, here into tmp_path)."""
    page = (Path(__file__).resolve().parents[2] / "docs/plan.md").read_text()
    argv = ["plan", "--robot", "ur5e", "--target", BOARD, "--fov-deg", "60", "--resolution",
            "640x480", "--board-pose", "-472,-133,3", "--count", "12", "--keep-out",
            "-300,50,0,-100,400,600", "--out", str(tmp_path / "plan"), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    line = capsys.readouterr().out.strip()
    assert line in page
    assert "--board-pose -472,-133,3 --count 12 --keep-out -300,50,0,-100,400,600" in page
