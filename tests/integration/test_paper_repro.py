"""``selfcal paper``: the reproduction of the paper's tables from the simulation.

The nominal tool tips at the five Table II postures (IK with the Cartesian tool pitch of Table II
row 1 held, -138.54 deg) must equal Table II within 0.1 mm (the table prints 0.1 mm). Caveat: Table
II's "Pitch (theta4) = -63.54 deg" read as the joint angle leaves row 2 out of reach (by 7.3 mm);
the reproduction reports that distance per row, and it is checked here against the closed form
(tests/unit/test_paper_tables.py derives it). The run itself (the
default rendered scenario plus the five postures, ~10 s) must leave parseable tables and figure.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from selfcal.cli.main import main as cli_main
from selfcal.config.paper_data import TABLE_II_MM, TABLE_II_THETA4_DEG, table_ii_postures
from selfcal.kinematics.forward import fk_nominal
from selfcal.robot.definition import load_robot
from selfcal.studies.paper.checks import paper_inconsistencies


def test_table_ii_postures_reproduce_table_ii():
    robot = load_robot("er4u-paper")
    q, pitch, roll = table_ii_postures(robot)
    robot.check_joints(q)
    tips_mm = fk_nominal(robot, q)[:, -1, :3, 3] * 1000
    np.testing.assert_allclose(tips_mm, TABLE_II_MM, atol=0.1)
    assert np.degrees(pitch) == pytest.approx(-138.54, abs=1e-6)
    assert roll == pytest.approx(0.0, abs=1e-9)


def test_paper_inconsistencies_found_from_the_tables():
    found = {(t["position"], t["axis"], t["kind"]) for t in paper_inconsistencies()}
    # Table IV row 1 p_z measured 190.00 vs Table III's 183.00; row 2 p_z 183.00 vs 182.80;
    # row 3 p_z printed error 0.70 while measured - desired = 198.00 - 197.70 = 0.30.
    assert found == {
        (1, "p_z", "Table IV measured != Table III measured"),
        (2, "p_z", "Table IV measured != Table III measured"),
        (3, "p_z", "Table IV error != measured - desired"),
    }


@pytest.fixture(scope="module")
def paper_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    # through the real parser: -q/--quiet is the CLI's, not the paper command's
    assert cli_main(["paper", "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.slow
def test_paper_outputs_exist_and_parse(paper_out):
    for name in ("paper.md", "table_ii.md", "table_iv.md", "paper_typos.md", "fig3.png"):
        assert (paper_out / name).is_file() and (paper_out / name).stat().st_size > 0, name
    assert (paper_out / "fig3.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((paper_out / "paper.json").read_text())
    with open(paper_out / "table_ii.csv") as fh:
        rows_ii = list(csv.DictReader(fh))
    assert len(rows_ii) == 5
    ours = np.array([[float(r[f"ours_p{a}_mm"]) for a in "xyz"] for r in rows_ii])
    np.testing.assert_allclose(ours, TABLE_II_MM, atol=0.1)
    dist = [float(r["theta4_held_distance_mm"]) for r in rows_ii]
    # the row-2 caveat: distance from the shoulder axis minus the arm's reach with theta4 held
    robot = load_robot("er4u-paper")
    a1, d1, a2, a3, d5 = robot.dh.a[0], robot.dh.d[0], robot.dh.a[1], robot.dh.a[2], robot.dh.d[4]
    th4 = np.radians(TABLE_II_THETA4_DEG)
    reach = a2 + np.hypot(a3 + d5 * np.sin(th4), d5 * np.cos(th4))
    p = TABLE_II_MM[1] / 1000
    rho = np.hypot(np.hypot(p[0], p[1]) - a1, p[2] - d1)
    assert dist[1] == pytest.approx((rho - reach) * 1000, abs=1e-3)  # the CSV prints 1e-3 mm
    assert max(dist[0], *dist[2:]) < 1e-3
    with open(paper_out / "table_iv.csv") as fh:
        rows_iv = list(csv.DictReader(fh))
    assert len(rows_iv) == 15
    # The desired column is the nominal MCPC model with the camera tool (another code path than
    # the DH FK above): it must also equal Table II within 0.1 mm.
    desired = np.array([float(r["desired"]) for r in rows_iv]).reshape(5, 3)
    np.testing.assert_allclose(desired, TABLE_II_MM, atol=0.1)
    # The camera measures the tool tip far better than the injected errors move it (measured -
    # true well under the nominal model's error), and calibration removes most of the error.
    cam = np.array([float(r["camera_error_measured_minus_true"]) for r in rows_iv])
    nom = np.array([float(r["nominal_error_desired_minus_true"]) for r in rows_iv])
    assert np.all(np.isfinite(cam))
    assert np.sqrt(np.mean(cam**2)) < 0.25 * np.sqrt(np.mean(nom**2))
    v = summary["validation"]
    assert v["calibrated_rms_mm"] < 0.5 * v["nominal_rms_mm"]
