"""Robot files carry the robot-specific numbers: planning window, simulation gains, MJCF entry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.robot.definition import (
    DEFAULT_KP,
    DEFAULT_SPAN_DEG,
    RobotDefinitionError,
    load_robot,
    robot_files,
)

PAPER = robot_files()["er4u-paper"]


def _variant(tmp_path: Path, drop: tuple[str, ...] = (), append: str = "") -> Path:
    """The er4u-paper file without the tables in ``drop``, plus ``append``."""
    out, skip = [], False
    for line in PAPER.read_text().splitlines():
        if line.startswith("["):
            skip = line.strip("[] ") in drop
        if not skip:
            out.append(line)
    p = tmp_path / "variant.toml"
    p.write_text("\n".join(out) + "\n" + append)
    return p


def test_planning_and_simulation_come_from_the_file():
    robot = load_robot("er4u-paper")
    np.testing.assert_allclose(np.degrees(robot.planning_span), [60, 45, 60, 80, 270])
    np.testing.assert_allclose(robot.simulation.kp, [500, 1000, 600, 100, 20])
    assert robot.simulation.kv.shape == robot.simulation.armature.shape == (robot.n,)


def test_absent_tables_give_generic_defaults(tmp_path):
    robot = load_robot(_variant(tmp_path, drop=("planning", "simulation")))
    np.testing.assert_allclose(np.degrees(robot.planning_span), DEFAULT_SPAN_DEG)
    np.testing.assert_allclose(robot.simulation.kp, DEFAULT_KP)


@pytest.mark.parametrize(
    "table,key,value",
    [("planning", "span_deg", "[60.0, 45.0]"), ("simulation", "kp", "[1, 2, 3, 4, -5]")],
)
def test_bad_values_name_file_table_and_key(tmp_path, table, key, value):
    p = _variant(tmp_path, drop=(table,), append=f"[{table}]\n{key} = {value}\n")
    with pytest.raises(
        RobotDefinitionError, match=rf"variant.toml: \[{table}\]: '{key}' must be 5"
    ):
        load_robot(p)


def test_encoder_tables_come_from_the_file():
    """er4u-vendor states the controller's table (docs/hardware.md: counts per 90 deg, signs,
    zero at the vendor home); er4u-paper derives it from its read-back resolution, zero at home."""
    vendor = load_robot("er4u-vendor").encoder
    assert vendor is not None and vendor.zero_stated and vendor.differential == (3, 4)
    per_90 = vendor.counts_per_unit * np.radians(90.0)
    np.testing.assert_allclose(per_90, [-12770, -10216, 10216, 2511, 2511], rtol=1e-12)
    np.testing.assert_allclose(np.degrees(vendor.zero), [0.0, 120.28, -95.02, -88.81, 0.0])
    paper = load_robot("er4u-paper")
    assert paper.encoder is not None and not paper.encoder.zero_stated
    np.testing.assert_allclose(paper.encoder.zero, paper.home)
    per_deg = paper.encoder.counts_per_unit * np.radians(1.0)
    np.testing.assert_allclose(per_deg, [-141.89, -113.51, 113.51, 27.9, 27.9], rtol=1e-12)


def test_a_robot_without_encoder_data_is_valid(tmp_path):
    robot = load_robot(_variant(tmp_path, drop=("encoder",)))
    assert robot.encoder is None and not np.isfinite(robot.counts_per_unit).any()


@pytest.mark.parametrize(
    "lines,match",
    [
        ("signs = [1, 0, 1, 1, 1]", "signs must be"),
        ("differential_joints = [4, 4]", "differential_joints must be"),
        ("zero_deg = [0.0, 1.0]", "zero_deg must be 5"),
        ("counts_per_degree = [1, 1, 1, 1, 1]", "unknown key"),
        ("differential_joints = [3, 4]", "counts_per_deg gives 113.51 and 55.8"),
    ],
)
def test_bad_encoder_keys_name_file_and_key(tmp_path, lines, match):
    text = "[encoder]\ncounts_per_deg = [141.89, 113.51, 113.51, 55.80, 55.80]\n" + lines + "\n"
    p = _variant(tmp_path, drop=("encoder",), append=text)
    with pytest.raises(RobotDefinitionError, match=rf"variant.toml: \[encoder\] {match}"):
        load_robot(p)
