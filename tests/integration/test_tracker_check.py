"""``selfcal check``: new tracker rows against a calibration, exit 0 unchanged / 5 changed (#29)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import selfcal
from selfcal.cli.check import EXIT_CHANGED
from selfcal.cli.main import main
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot
from tests.integration.test_tracker_cli import SIGMA, _measurements, _write


@pytest.mark.slow
def test_check_says_unchanged_or_changed_with_its_exit_code(tmp_path, capsys):
    robot = load_robot("er4u-paper")
    case, header, rows = _measurements(tmp_path, robot, m=30)
    out = tmp_path / "cal"
    argv = ["identify", _write(tmp_path / "m.csv", header, rows), "--robot", "er4u-paper",
            "--joint-units", "deg", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    q = case.configurations(5, 77)
    T = fk_tool(case.true, q)
    noise = np.random.default_rng(3).normal(0.0, SIGMA, (5, 3))
    files = {}
    for name, shift_m in (("same", 0.0), ("moved", 1e-3)):
        xyz = (T @ np.array([shift_m, 0.0, 0.0, 1.0]))[:, :3] + noise
        files[name] = _write(tmp_path / f"{name}.csv", header, np.c_[np.degrees(q), xyz * 1e3])
    check = ["check", str(out), "--joint-units", "deg"]
    assert main([*check[:2], files["same"], *check[2:]]) == 0
    assert capsys.readouterr().out.startswith("unchanged: 5 new rows within")
    assert main([*check[:2], files["moved"], *check[2:], "--json"]) == EXIT_CHANGED
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"] == "changed" and doc["p_value"] < 0.01 and doc["dof"] == 15
    assert 0.7 < doc["change_mm"] < 1.1  # a 1 mm shift of the tool, less the predicted spread
    api = selfcal.check_tracker(
        out, files["moved"], "deg"
    )  # the check is the route's, not the CLI's
    assert api.changed and api.to_json() == doc
    assert main(["check", str(tmp_path), files["same"], "--joint-units", "deg"]) == 2
    assert "not found" in capsys.readouterr().err
