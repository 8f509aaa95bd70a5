"""Measurement terms' sections in calibration.json (selfcal.io.calibration_terms, selfcal.terms).

A calibration estimated with further measurements lists ``sources`` ("images" and each term's
kind) and writes each term's section under its kind; a file written before terms existed (a
tracker section, the only kind then) reads the same, a kind the reader does not know is kept as
written, and the registry reads every kind it knows as its type.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from selfcal.calibration.field.calibrate import calibrate
from selfcal.errors import InputError
from selfcal.io.calibration import (
    CalibrationFileError,
    CalibrationResult,
    read_calibration,
    write_calibration,
)
from selfcal.io.calibration_terms import RawSection
from selfcal.io.calibration_tracker import TrackerSource
from selfcal.terms import registry
from selfcal.terms.probe import ProbeTerm

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "analytic" / "calibration.json"


def _golden() -> CalibrationResult:
    return CalibrationResult.from_json(json.loads(GOLDEN.read_text()), "golden")


def _tracker() -> TrackerSource:
    T = np.eye(4)
    T[:3, 3] = [0.1, -0.2, 0.3]
    return TrackerSource(
        file="tracker.csv", distances_file=None, joint_units="deg", kinds=("positions",),
        rows=12, distances=0, sigma_mm=0.1, sigma_deg=0.01, rms_mm={"positions": 0.15},
        T_tracker_world_m=T, tool_point_mm=(1.0, 2.0, 3.0), T_cam_tool_m=None,
    )  # fmt: skip


def test_sections_are_written_under_their_kinds_after_sources(tmp_path):
    raw = RawSection("probe", {"points": 4, "rms_mm": 0.01})
    res = dataclasses.replace(_golden(), terms=(_tracker(), raw))
    doc = json.loads(write_calibration(tmp_path / "calibration.json", res).read_text())
    assert doc["sources"] == ["images", "tracker", "probe"]
    assert doc["tracker"] == _tracker().to_json() and doc["probe"] == raw.doc
    keys = list(doc)
    assert (
        keys.index("sources") < keys.index("tracker") < keys.index("probe") < keys.index("method")
    )


def test_a_file_with_a_tracker_section_reads_typed_through_the_registry_and_raw_without(tmp_path):
    res = dataclasses.replace(_golden(), terms=(_tracker(),))
    path = write_calibration(tmp_path / "calibration.json", res)
    text = path.read_text()
    typed = registry.read_calibration(path).section("tracker")
    assert isinstance(typed, TrackerSource) and typed.tool_point_mm == (1.0, 2.0, 3.0)
    assert typed.summary().startswith("tracker: 12 positions estimated with the images")
    raw = read_calibration(path).section("tracker")
    assert isinstance(raw, RawSection) and raw.to_json() == _tracker().to_json()
    # either way the file is written back byte for byte
    for back in (registry.read_calibration(path), read_calibration(path)):
        assert write_calibration(tmp_path / "back.json", back).read_text() == text


def test_a_file_without_sources_has_no_sections():
    assert _golden().terms == () and _golden().section("tracker") is None


@pytest.mark.parametrize(
    "sources", [["tracker"], ["images", "tracker", "tracker"], ["images", "probe"]]
)
def test_bad_sources_or_a_missing_section_name_the_file_and_the_key(tmp_path, sources):
    doc = _golden().to_json() | {"sources": sources, "tracker": _tracker().to_json()}
    (tmp_path / "calibration.json").write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError, match=r"calibration.json.*'(sources|probe)'"):
        registry.read_calibration(tmp_path)


def test_a_malformed_registered_section_names_its_key(tmp_path):
    bad = _tracker().to_json() | {"rows": "twelve"}
    doc = _golden().to_json() | {"sources": ["images", "tracker"], "tracker": bad}
    (tmp_path / "calibration.json").write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError, match=r"'tracker\.rows'"):
        registry.read_calibration(tmp_path)


def test_no_kind_takes_a_key_of_the_calibration_itself():
    """A section is a top-level key: a kind named like one (``joint``, ``scene``) would clash."""
    res = dataclasses.replace(_golden(), terms=(_tracker(),))
    own = set(res.to_json()) - {k.name for k in registry.KINDS}
    names = [k.name for k in registry.KINDS]
    assert len(set(names)) == len(names) and not own & set(names)
    assert all(getattr(k.section, "kind", k.name) == k.name for k in registry.KINDS)


def test_two_terms_of_one_kind_are_refused_before_the_calibration_starts(tmp_path):
    probe = ProbeTerm(np.zeros((2, 5)), np.zeros((1, 3)), np.zeros(2, np.int64))
    with pytest.raises(InputError, match="kind probe are given more than once"):
        calibrate(tmp_path / "no-such-dataset", terms=[probe, probe])
