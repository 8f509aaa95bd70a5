"""Tracker files: joint units of prismatic joints, separators, the tracker calibration.json."""

from __future__ import annotations

import json

import hypothesis.strategies as st
import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis.extra.numpy import arrays

from selfcal.benchmarks.tracker.sim import RRPRR_DH, dh_robot, make_case, measure
from selfcal.calibration.tracker.calibration_file import (
    SCHEMA_VERSION,
    TrackerCalibrationFileError,
    from_result,
    read_tracker_calibration,
    write_tracker_calibration,
)
from selfcal.calibration.tracker.identify import TrackerMeasurements, identify_tracker
from selfcal.io.tracker import TrackerFileError, joints_to_si, read_joints, read_table


def rrprr():
    return dh_robot("rrprr", **RRPRR_DH)


def test_prismatic_joints_are_mm_with_degrees_and_m_with_radians(tmp_path):
    robot = rrprr()
    (tmp_path / "deg.txt").write_text("10 20 150 30 40\n-10 -20 250.5 -30 -40\n")
    (tmp_path / "rad.csv").write_text("j1,j2,j3,j4,j5\n0.1,0.2,0.15,0.3,0.4\n")
    q = read_joints(tmp_path / "deg.txt", robot, "deg")
    np.testing.assert_allclose(q[:, 2], [0.15, 0.2505])
    np.testing.assert_allclose(q[0, [0, 1, 3, 4]], np.radians([10, 20, 30, 40]))
    q = read_joints(tmp_path / "rad.csv", robot, "rad")
    np.testing.assert_allclose(q[0], [0.1, 0.2, 0.15, 0.3, 0.4])
    # 150 m is out of the prismatic range: the message names the row, column and mm
    (tmp_path / "bad.csv").write_text("j1,j2,j3,j4,j5\n0.1,0.2,150,0.3,0.4\n")
    with pytest.raises(TrackerFileError, match=r"row 1 \(line 2\), column j3: 150 m is outside"):
        read_joints(tmp_path / "bad.csv", robot, "rad")


def test_comments_blank_lines_and_whitespace(tmp_path):
    (tmp_path / "t.txt").write_text("# a comment\n\nj1 j2\n 1.5  2\n\n3 4e-1\n")
    t = read_table(tmp_path / "t.txt")
    assert t.columns == ("j1", "j2") and t.has_header
    np.testing.assert_allclose(t.values, [[1.5, 2.0], [3.0, 0.4]])
    assert t.lines.tolist() == [4, 6]
    with pytest.raises(TrackerFileError, match="--joint-units must be deg or rad"):
        joints_to_si(t, ["j1", "j2"], rrprr(), "grad")


def _calibration(tmp_path):
    robot = rrprr()
    case = make_case(robot, seed=2)
    q = case.configurations(40, 1)
    xyz, _ = measure(case, q, 1e-4, 2)
    res = identify_tracker(case.nominal, TrackerMeasurements(q, xyz))
    cal = from_result(
        res,
        case.nominal,
        robot=robot.name,
        robot_source="rrprr",
        joint_names=robot.joint_names,
        joint_limits=robot.limits,
        joint_units="deg",
        sigmas={"position_mm": 0.1},
        files={"measurements": "m.csv"},
    )
    return res, q, write_tracker_calibration(tmp_path / "calibration.json", cal)


def test_tracker_calibration_round_trip(tmp_path):
    res, q, path = _calibration(tmp_path)
    cal = read_tracker_calibration(path)
    np.testing.assert_allclose(cal.predict(q), res.predict(q), atol=1e-12)
    assert cal.identifiable == res.identifiable and cal.rank == res.rank
    assert set(cal.held) == {"alpha5", "beta5", "gamma5"}
    ang = np.array([u == "deg" for u in cal.units])
    np.testing.assert_allclose(cal.values[~ang], res.values[~ang] * 1e3)
    np.testing.assert_allclose(cal.std[ang], np.degrees(res.std[ang]))


def test_newer_or_damaged_tracker_calibration_is_refused(tmp_path):
    _, _, path = _calibration(tmp_path)
    doc = json.loads(path.read_text())
    written = doc["schema_version"]
    doc["schema_version"] = SCHEMA_VERSION + 1
    path.write_text(json.dumps(doc))
    with pytest.raises(TrackerCalibrationFileError, match="newer than this scorbot-selfcal"):
        read_tracker_calibration(path)
    doc["schema_version"] = written
    del doc["mcpc"]["params"]
    path.write_text(json.dumps(doc))
    with pytest.raises(TrackerCalibrationFileError, match="missing key 'mcpc.params'"):
        read_tracker_calibration(path)


@settings(max_examples=examples(40), deadline=None)
@given(
    values=arrays(
        float,
        st.tuples(st.integers(1, 6), st.integers(1, 5)),
        elements=st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False),
    ),
    sep=st.sampled_from([",", ", ", " ", "\t", "   "]),
    header=st.booleans(),
)
def test_read_table_round_trips_any_numbers_and_separators(tmp_path_factory, values, sep, header):
    path = tmp_path_factory.mktemp("t") / "t.txt"
    cols = [f"c{i + 1}" for i in range(values.shape[1])]
    lines = ([sep.join(cols)] if header else []) + [
        sep.join(repr(float(v)) for v in r) for r in values
    ]
    path.write_text("\n".join(lines) + "\n")
    t = read_table(path, header=header)
    assert t.columns == tuple(cols) and t.has_header == header
    np.testing.assert_array_equal(t.values, values)


@pytest.mark.parametrize(
    ("key", "value"),
    [("params", "nan"), ("joint_offsets", "inf"), ("T_meas_fit", "scaled")],
)
def test_a_tracker_calibration_of_non_finite_or_non_rigid_values_is_refused(tmp_path, key, value):
    """#33: the readers of every calibration.json check what they read (before: NaN and a scaled
    tracker transform were read and predicted from without a word)."""
    _, _, path = _calibration(tmp_path)
    doc = json.loads(path.read_text())
    a = np.array(doc["mcpc"][key], float)
    doc["mcpc"][key] = (a * 2 if value == "scaled" else np.full_like(a, float(value))).tolist()
    path.write_text(json.dumps(doc))
    with pytest.raises(TrackerCalibrationFileError, match=rf"key 'mcpc.{key}' must be"):
        read_tracker_calibration(path)


def test_the_fair_nominal_keeps_its_base_offset():
    """A chain whose joint 1 lies along its base x-axis has a base offset of 90 deg; the fair
    nominal recorded in the tracker calibration keeps it (without it the nominal tool moved by
    0.3 m and `selfcal predict` printed a wrong nominal error)."""
    from selfcal.calibration.tracker.calibration_file import _nominal_from, _nominal_json
    from selfcal.calibration.tracker.nominal import NominalFit
    from selfcal.io.jsonfile import Fields
    from selfcal.kinematics.forward import fk_frames
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot, models_dir

    robot = load_robot(str(models_dir().parent / "tests" / "data" / "virtual_chain_xyz.urdf"))
    model = nominal_mcpc(robot)
    assert abs(model.base_offset) == pytest.approx(np.pi / 2)
    nom = NominalFit(model, np.eye(4), 1.0, float("nan"), float("nan"), True)
    doc = json.loads(json.dumps(_nominal_json(nom)))
    back = _nominal_from(Fields(doc, "nominal", "fix"), model.joint_types)
    assert back.model.base_offset == model.base_offset
    q = np.random.default_rng(4).uniform(robot.limits[:, 0], robot.limits[:, 1], (5, 6)) * 0.2
    np.testing.assert_allclose(
        fk_frames(back.model, q)[:, -1], fk_frames(model, q)[:, -1], atol=1e-12
    )
