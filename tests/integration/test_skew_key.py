"""The scenario key camera.skew_px: a true skew that the simulation projects and the field's
self-calibration estimates when ``free`` names ``skew`` (analytic path)."""

from __future__ import annotations

import json

import pytest

from selfcal.cli.main import main

SCENARIO = """
[camera]
model = "opencv"
principal_point_offset_px = [12.0, -8.0]
skew_px = 1.5
distortion = { k1 = -0.25, k2 = 0.1, p1 = 1e-3, p2 = -5e-4 }
free = ["fx", "mu", "cx", "cy", "skew", "k1", "k2", "p1", "p2"]
[trajectory]
poses = 16
[validation]
poses = 3
[noise]
render = false
"""


@pytest.mark.slow  # 2-3 s
def test_a_true_skew_is_estimated_within_3_sigma(tmp_path):
    cfg = tmp_path / "skew.toml"
    cfg.write_text(SCENARIO)
    assert main(["run", str(cfg), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    truth = json.loads((tmp_path / "run" / "truth.json").read_text())
    assert truth["cameras"]["left"]["skew"] == 1.5
    rep = json.loads((tmp_path / "run" / "report.json").read_text())
    skew = rep["intrinsics"]["skew"]
    assert skew["truth"] == 1.5
    assert abs(skew["estimate"] - 1.5) < 3 * skew["std"] < 1.0  # measured 1.63 +- 0.13 (30 poses)
    for name, row in rep["intrinsics"].items():
        if row.get("std"):
            assert abs(row["estimate"] - row["truth"]) < 3 * row["std"], name
