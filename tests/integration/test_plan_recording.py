"""docs/plan.md "From the plan to a recording and back", as a new user follows it with the
simulated robot standing in for the real one: `selfcal plan`, the plan's scenario rendered as
the recording (the images and the read-back joints the simulator logs), the read-back joints
written as step 3 shows them, and step 4's `selfcal import` and `selfcal calibrate` run as typed
on the page."""

from __future__ import annotations

import csv
import json
import shlex
import shutil
from pathlib import Path

import pytest

from selfcal.cli.main import main
from selfcal.robot.definition import models_dir

PAGE = Path(__file__).resolve().parents[2] / "docs/plan.md"


def _step4_commands() -> list[list[str]]:
    """The commands of step 4's shell block, continuation lines joined, without `selfcal`."""
    text = PAGE.read_text()
    step = text[text.index("4. Import and calibrate") :]
    block = step[step.index("```sh") + len("```sh") : step.index("```", step.index("```sh") + 5)]
    lines = block.replace("\\\n", " ").strip().splitlines()
    out = [shlex.split(line) for line in lines if line.strip()]
    assert all(c[0] == "selfcal" for c in out), out
    return [c[1:] for c in out]


@pytest.mark.slow
def test_the_documented_recording_imports_and_calibrates(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    board = str(models_dir() / "targets/charuco.toml")
    assert main(["plan", "--robot", "ur5e", "--target", board, "--fov-deg", "60",
                 "--resolution", "640x480", "--board-pose", "-472,-133,3", "--count", "12",
                 "--candidates", "60", "--keep-out", "-300,50,0,-100,400,600", "--out",
                 "runs/plan-ur5e", "--quiet"]) == 0  # fmt: skip
    scenario = Path("runs/plan-ur5e/scenario.toml")
    scenario.write_text(scenario.read_text().replace("render = false", "render = true"))
    assert main(["run", str(scenario), "--out", "sim", "--quiet"]) == 0  # the recording
    Path("shots").mkdir()
    with open("sim/joints.csv") as f:
        logged = list(csv.DictReader(f))
    with open("readback.csv", "w") as f:  # step 3's read-back log
        f.write("image,j1,j2,j3,j4,j5,j6\n")
        for row in logged:
            name = f"{int(row['index']):04d}.png"
            shutil.copyfile(f"sim/frames/{int(row['index']):04d}_left.png", f"shots/{name}")
            f.write(name + "," + ",".join(row[f"q{k}_deg"] for k in range(1, 7)) + "\n")
    commands = _step4_commands()
    assert [c[0] for c in commands] == ["import", "calibrate"]
    for argv in commands:
        assert main([*argv, "--quiet"]) == 0, argv
    doc = json.loads(Path("my-dataset/calibration.json").read_text())
    assert len(logged) == 12 and doc["dataset"]["frames_used"] == 12  # every planned posture
    # rendered corners: 0.057 px on the example's 12 postures (measured), the nominal 1.1 px
    assert doc["reprojection_rms_px"] < 0.2 < doc["nominal_reprojection_rms_px"]
    capsys.readouterr()
