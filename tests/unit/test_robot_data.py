"""Robot files carry the robot-specific numbers: planning window, simulation gains, MJCF entry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib.robot_def import (
    DEFAULT_KP,
    DEFAULT_SPAN_DEG,
    RobotDefinitionError,
    load_robot,
    models_dir,
)

PAPER = models_dir() / "robots" / "er4u-paper.toml"


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
