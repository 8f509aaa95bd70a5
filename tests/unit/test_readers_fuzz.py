"""Totality of the file readers (issue #15): any text given as a scenario, robot file, target
file or tracker CSV ends in a value or the reader's typed error (an InputError subclass naming the
file), never another exception. Inputs: arbitrary text, and the shipped files with one or more
values replaced by other TOML values (NaN, inf, huge, wrong types, empty lists, tables)."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib.errors import SelfCalError
from calib.io.target_toml import TargetFileError, load_target
from calib.io.tracker import TrackerFileError, read_distances, read_joints, read_measurements
from calib.robot_def import RobotDefinitionError, load_robot, models_dir
from scenarios.config import ConfigError, default_scenario_path, load_scenario

REPO = Path(__file__).resolve().parents[2]
VALUE_LINE = re.compile(r"^(\s*[A-Za-z_][\w.]*\s*=\s*)(.+?)\s*(#.*)?$")

TOML_VALUES = st.one_of(
    st.sampled_from(
        [
            "nan",
            "inf",
            "-inf",
            "-nan",
            "1e309",
            "1e-300",
            "0",
            "-1",
            "0.0",
            "true",
            '"x"',
            '""',
            "[]",
            "[nan, inf, 1]",
            "[1]",
            "[1, 2, 3, 4, 5, 6, 7, 8]",
            '["a", "b"]',
            "{}",
            "{ a = 1 }",
            "9" * 5000,
            "-" + "9" * 30,
            "1979-05-27",
            "[[1, 2], [3]]",
        ]
    ),  # fmt: skip
    st.floats(allow_nan=True, allow_infinity=True).map(
        lambda x: {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(repr(x), repr(x))
    ),
    st.integers(-(10**30), 10**30).map(str),
    st.text(alphabet="abcXYZ_ 0123456789", max_size=8).map(lambda s: f'"{s}"'),
)


def mutations(text: str):
    """A strategy of ``text`` with 1-3 value lines replaced by TOML values or deleted."""
    lines = text.splitlines()
    idx = [i for i, line in enumerate(lines) if VALUE_LINE.match(line)]

    @st.composite
    def mutate(draw):
        out = list(lines)
        for _ in range(draw(st.integers(1, 3))):
            i = draw(st.sampled_from(idx))
            if draw(st.integers(0, 5)) == 0:
                out[i] = ""
            else:
                m = VALUE_LINE.match(lines[i])
                out[i] = m.group(1) + draw(TOML_VALUES)
        return "\n".join(out) + "\n"

    return mutate()


ANY_TEXT = st.one_of(
    st.text(max_size=300), st.binary(max_size=200).map(lambda b: b.decode("latin-1"))
)


def _file(text: str, name: str) -> Path:
    d = Path(tempfile.mkdtemp())
    p = d / name
    p.write_text(text, encoding="utf-8", errors="surrogateescape")
    return p


def _total(fn, path: Path, typed: type[SelfCalError], check=None) -> None:
    """``fn(path)`` returns (a value ``check`` accepts) or raises ``typed`` naming the file."""
    try:
        value = fn(path)
    except typed as exc:
        assert str(path) in str(exc) or path.name in str(exc), str(exc)
        return
    if check is not None:
        check(value)


def _finite_robot(robot) -> None:
    """A loaded robot carries no NaN or infinity into the maths (ranges may be infinite)."""
    for arr in (robot.chain, robot.home, robot.T_flange_cam, robot.planning_span):
        assert np.all(np.isfinite(arr)), robot
    assert not np.any(np.isnan(robot.limits))


FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.one_of(mutations(default_scenario_path().read_text()), ANY_TEXT))
def test_scenario_loader_is_total(text):
    _total(load_scenario, _file(text, "scenario.toml"), ConfigError)


@FUZZ
@given(st.one_of(mutations((models_dir() / "robots" / "er4u-paper.toml").read_text()), ANY_TEXT))
def test_robot_file_reader_is_total(text):
    _total(load_robot, _file(text, "arm.toml"), RobotDefinitionError, _finite_robot)


@FUZZ
@given(
    st.one_of(
        *(mutations(p.read_text()) for p in sorted((models_dir() / "targets").glob("*.toml"))),
        ANY_TEXT,
    )
)
def test_target_reader_is_total(text):
    _total(load_target, _file(text, "target.toml"), TargetFileError)


CELL = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**6), 10**6).map(str),
    st.sampled_from(["", "x", "nan", "1e309", "9" * 5000, "1,2", "#", " ", "j1"]),
)


@st.composite
def tracker_csv(draw):
    header = draw(
        st.sampled_from(
            [
                "j1,j2,j3,j4,j5,x_mm,y_mm,z_mm",
                "j1,j2,j3,j4,j5,x_mm,y_mm,z_mm,qw,qx,qy,qz",
                "a_j1,a_j2,a_j3,a_j4,a_j5,b_j1,b_j2,b_j3,b_j4,b_j5,d_mm",
                "j1 j2 j3 j4 j5",
                "",
            ]
        )
    )
    n = max(len(re.split(r"[,\s]+", header)), 5)
    sep = "," if "," in header else " "
    rows = draw(
        st.lists(
            st.lists(CELL, min_size=n - 1, max_size=n + 1).map(lambda r: sep.join(r)), max_size=6
        )
    )
    return "\n".join([header, *rows]) + "\n"


@pytest.fixture(scope="module")
def er4u():
    return load_robot("er4u-paper")


@FUZZ
@given(st.one_of(tracker_csv(), ANY_TEXT), st.sampled_from(["deg", "rad"]))
def test_tracker_readers_are_total(er4u, text, units):
    path = _file(text, "MEASUREMENTS.csv")
    for read in (read_measurements, read_distances, read_joints):
        _total(lambda p, read=read: read(p, er4u, units), path, TrackerFileError)
