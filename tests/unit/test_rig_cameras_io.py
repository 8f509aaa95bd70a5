"""calibration.json of a rig whose cameras have their own intrinsics (#12, rigs of N cameras):
``cameras`` lists each camera's own block, the file is schema 2 (code reading schema 1 refuses
it rather than taking the first camera's intrinsics for both), and it round-trips byte for byte;
a shared camera's file stays schema 1 without the key."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from selfcal.camera import camera_model
from selfcal.io.calibration import (
    CalibrationFileError,
    CalibrationResult,
    read_calibration,
    write_calibration,
)
from selfcal.io.calibration_blocks import CameraIntrinsics, RigCamera
from selfcal.io.calibration_bounds import CameraBounds
from selfcal.io.jsonfile import check_header

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "analytic" / "calibration.json"
FREE = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2")


def _per_camera() -> CalibrationResult:
    base = CalibrationResult.from_json(json.loads(GOLDEN.read_text()), "golden")
    left = camera_model("opencv", fx=801.0, mu=1.001, cx=331.7, cy=231.2, width=640, height=480,
                        coeffs={"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4}, free=FREE)  # fmt: skip
    right = camera_model("pinhole", fx=790.0, mu=0.998, cx=318.0, cy=241.0, width=640,
                         height=480, free=("fx", "mu", "cx", "cy"))  # fmt: skip
    std = {"fx": 0.5, "mu": 1e-4}
    cams = (RigCamera("left", CameraIntrinsics.of(left, std)),
            RigCamera("right", CameraIntrinsics.of(right, std)))  # fmt: skip
    bounds = base.bounds
    if bounds is not None:
        bounds = dataclasses.replace(
            bounds, cameras=(CameraBounds("left", {"fx": 0.4}), CameraBounds("right", {"fx": 0.6}))
        )
    return dataclasses.replace(base, intrinsics=cams[0].intrinsics, cameras=cams, bounds=bounds)


def test_per_camera_intrinsics_round_trip_as_schema_2(tmp_path):
    a = write_calibration(tmp_path / "a.json", _per_camera())
    back = read_calibration(a)
    b = write_calibration(tmp_path / "b.json", back)
    assert a.read_bytes() == b.read_bytes()
    doc = json.loads(a.read_text())
    assert doc["schema_version"] == 2
    assert [c["name"] for c in doc["cameras"]] == ["left", "right"]
    assert back.intrinsics_of(1).model == "pinhole" and back.intrinsics_of(1).fx == 790.0
    assert back.intrinsics_of(0).camera().model_name == "opencv"
    assert back.intrinsics_of(0) == back.intrinsics
    if back.bounds is not None:
        assert [c.name for c in back.bounds.cameras] == ["left", "right"]


def test_schema_1_code_refuses_a_per_camera_file(tmp_path):
    doc = json.loads(write_calibration(tmp_path / "c.json", _per_camera()).read_text())
    with pytest.raises(CalibrationFileError, match="newer"):
        check_header(doc, "c.json", fmt=doc["format"], version=1, fix="-",
                     error=CalibrationFileError)  # fmt: skip


def test_a_shared_camera_file_stays_schema_1_without_cameras(tmp_path):
    base = CalibrationResult.from_json(json.loads(GOLDEN.read_text()), "golden")
    doc = json.loads(write_calibration(tmp_path / "s.json", base).read_text())
    assert doc["schema_version"] == 1 and "cameras" not in doc
    assert "cameras" not in doc.get("bounds", {})
    assert base.intrinsics_of(1) is base.intrinsics


def test_the_fit_report_lists_each_cameras_own_parameters():
    """Without truth (real data) the report lists each camera's free parameters with their std;
    a shared camera adds nothing."""
    from selfcal.pipeline.report_cameras import rig_camera_markdown, rig_camera_rows

    rows = rig_camera_rows(_per_camera(), None)
    assert list(rows) == ["left", "right"] and list(rows["right"]) == ["fx", "mu", "cx", "cy"]
    assert rows["right"]["fx"] == {"estimate": 790.0, "std": 0.5} and "z" not in rows["left"]["k1"]
    text = "\n".join(rig_camera_markdown(rows))
    assert "| right | fx | 790 | 0.5 |" in text and "truth" not in text
    base = CalibrationResult.from_json(json.loads(GOLDEN.read_text()), "golden")
    assert rig_camera_rows(base, None) == {} and rig_camera_markdown({}) == []
