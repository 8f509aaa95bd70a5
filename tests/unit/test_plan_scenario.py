"""A scenario with [target] board_pose: the random planner keeps the board where it is in view."""

from __future__ import annotations

import re

import numpy as np
import pytest

from selfcal.acquisition.backends import planning_inputs
from selfcal.acquisition.simulator_setup import sim_setup
from selfcal.config.scenario import load_scenario
from selfcal.target.placement import board_pose


def test_random_planner_aims_at_the_board_pose(tmp_path):
    (tmp_path / "s.toml").write_text(
        '[robot]\nmodel = "ur5e"\n[camera]\ncount = 1\n'
        '[target]\nboard = "' + str(_charuco()) + '"\nboard_pose = [-400, -250, 3, 0, 0, 20]\n'
    )
    s = load_scenario(tmp_path / "s.toml")
    setup = sim_setup(s)
    T = board_pose(setup.board, np.array([-0.4, -0.25, 0.003]), np.radians([0, 0, 20]))
    assert np.allclose(setup.T_world_board, T)
    inp = planning_inputs(s)
    _, pts = setup.board.layout()
    X = pts @ T[:3, :3].T + T[:3, 3]
    # the planning grid spans the board's features where the board is
    assert np.allclose(inp["points_world"].min(axis=0), X.min(axis=0), atol=1e-9)
    assert np.allclose(inp["points_world"].max(axis=0), X.max(axis=0), atol=1e-9)
    assert np.allclose(inp["normals_world"], -T[:3, 2])


def _charuco():
    from selfcal.robot.definition import models_dir

    return models_dir() / "targets/charuco.toml"


def test_a_static_camera_pose_is_refused_where_it_does_not_fit(tmp_path):
    import pytest

    from selfcal.config.camera import ConfigError

    board = f'[target]\nboard = "{_charuco()}"\n'
    cases = {
        "[camera]\ncount = 1\npose = [0, 0, 1000, 0, 0, 0]\n": "camera.pose places a static",
        '[camera]\ncount = 1\nsetup = "eye-to-hand"\npose = [0, 0, 1000]\n': "is [x, y, z, rx",
        '[camera]\ncount = 1\nsetup = "eye-to-hand"\n': None,
    }
    for text, says in cases.items():
        (tmp_path / "s.toml").write_text('[robot]\nmodel = "ur5e"\n' + text + board)
        if says is None:
            assert load_scenario(tmp_path / "s.toml").camera.pose == []
            continue
        with pytest.raises(ConfigError, match=re.escape(says)):
            load_scenario(tmp_path / "s.toml")
    (tmp_path / "s.toml").write_text('[robot]\nmodel = "ur5e"\n[camera]\ncount = 1\n'
                                     'setup = "eye-to-hand"\n' + board + "board_pose = [0, 0, 3]\n")  # fmt: skip
    with pytest.raises(ConfigError, match="leave target.board_pose out"):
        load_scenario(tmp_path / "s.toml")


def test_an_eye_to_hand_cell_simulates_an_arm_whose_flange_camera_never_sees_the_table(tmp_path):
    """A 2-axis positioner has no flange camera looking down at the table: its eye-to-hand
    scenario (as `selfcal plan --mount eye-to-hand` writes it) still simulates the board on the
    flange (sim_setup places neither a marker field nor a board on the table where the home
    flange camera would look); an eye-in-hand scenario of it is still refused, naming
    home_deg."""
    from pathlib import Path

    import pytest

    from selfcal.config.camera import ConfigError

    robot = Path(__file__).parents[1] / "data/positioner2.toml"
    head = f'[robot]\nmodel = "{robot}"\n[target]\nboard = "{_charuco()}"\n'
    (tmp_path / "s.toml").write_text(
        head + '[camera]\ncount = 1\nsetup = "eye-to-hand"\npose = [0, 600, 400, -56.3, 0, 180]\n'
    )
    setup = sim_setup(load_scenario(tmp_path / "s.toml"))
    assert setup.static is not None and setup.board is not None
    assert setup.field is None and setup.T_world_board is None
    (tmp_path / "s.toml").write_text(head + "[camera]\ncount = 1\n")
    with pytest.raises(ConfigError, match="home_deg in the robot file of positioner2"):
        sim_setup(load_scenario(tmp_path / "s.toml"))


def test_a_board_scenarios_simulation_has_no_marker_field(tmp_path):
    """A board scenario simulates the board alone: no marker field in the set-up, the analytic
    robot or truth.json (a field scenario's has one)."""
    from selfcal.acquisition.backends import make_kinematic_robot
    from selfcal.io.truth import Truth

    (tmp_path / "s.toml").write_text(
        f'[robot]\nmodel = "ur5e"\n[camera]\ncount = 1\n[target]\nboard = "{_charuco()}"\n'
    )
    (tmp_path / "f.toml").write_text('[robot]\nmodel = "ur5e"\n')
    for name, has_field in (("s.toml", False), ("f.toml", True)):
        s = load_scenario(tmp_path / name)
        setup = sim_setup(s)
        robot = make_kinematic_robot(s, setup)
        doc = robot.truth().to_json()
        assert (setup.field is not None, robot.field is not None) == (has_field, has_field)
        assert ("marker_field" in doc) == has_field
        assert (Truth.from_json(doc).marker_field is not None) == has_field
        assert (setup.T_world_board is not None) == (not has_field)


def test_what_renders_the_flange_cameras_refuses_an_eye_to_hand_scenario(tmp_path):
    """The emulator's rendered arm, `selfcal render` and the analytic robot put the cameras on the flange: an
    eye-to-hand scenario (its board on the flange, no board on the table since 62c2937) is
    refused by name, not an internal error from a board without a table pose."""
    from selfcal.acquisition.backends import make_kinematic_robot, make_sim_robot, render_posture
    from selfcal.config.scenario import ConfigError, scenarios_dir
    from selfcal.robot.definition import load_robot

    path = scenarios_dir() / "eye-to-hand.toml"
    named = re.escape(f'{path}: [camera] setup = "eye-to-hand"')
    with pytest.raises(ConfigError, match=named + ".*`selfcal emulate`"):
        make_sim_robot(load_scenario(path))
    with pytest.raises(ConfigError, match=named + ": the analytic flange-camera robot"):
        make_kinematic_robot(load_scenario(path))
    robot = load_robot("ur5e")
    with pytest.raises(ConfigError, match=named + ": `selfcal render` renders the cameras"):
        render_posture(robot, robot.home, tmp_path / "r", config=str(path))
    assert not (tmp_path / "r").exists()


def test_a_rendered_board_in_the_tables_plane_is_refused_naming_the_key_and_the_lift(tmp_path):
    """`selfcal plan --board-pose X,Y,0` wrote board_pose = [X, Y, 0, ...]: rendered, the print
    lay in the table's plane and the table hid parts of it (a 3-joint arm's replay lost 2 of 12
    frames and its calibration failed, 2.0 mm against the nominal's 1.6). The renderers now
    refuse it before anything is rendered, naming the file, the key and the lifted pose; the
    analytic path (no table in its images) and a board lying its thickness high are unchanged."""
    from selfcal.acquisition.backends import make_kinematic_robot, make_sim_robot, render_posture
    from selfcal.acquisition.simulator_setup import check_board_above_table
    from selfcal.config.scenario import ConfigError
    from selfcal.robot.definition import load_robot

    def scenario(pose: str, render: bool = True):
        path = tmp_path / "s.toml"
        path.write_text(
            f'[robot]\nmodel = "ur5e"\n[camera]\ncount = 1\n[target]\nboard = "{_charuco()}"\n'
            f"board_pose = [{pose}]\n[noise]\nrender = {str(render).lower()}\n"
        )
        return load_scenario(path)

    s = scenario("-400, -250, 0, 0, 0, 20")
    says = re.escape(f"{s.source}: target.board_pose = [-400.0, -250.0, 0.0, 0.0, 0.0, 20.0]: the "
                     "board's printed image reaches 0.0 mm above the table")  # fmt: skip
    lift = re.escape("board_pose = [-400.0, -250.0, 3.0, 0.0, 0.0, 20.0]")
    with pytest.raises(ConfigError, match=says) as err:
        sim_setup(s)  # what `selfcal run` and `acquire` set up before they write the dataset
    assert re.search(lift, str(err.value.fix))
    with pytest.raises(ConfigError, match=says):
        make_sim_robot(scenario("-400, -250, 0, 0, 0, 20", render=False))  # `selfcal emulate`
    robot = load_robot("ur5e")
    with pytest.raises(ConfigError, match=says):  # renders whatever [noise] render says
        render_posture(robot, robot.home, tmp_path / "r", config=str(s.source))
    assert not (tmp_path / "r").exists()
    # tilted 5 deg about x, its centre 3 mm high: one edge of the print 6.6 mm under the table
    s = scenario("-400, -250, 3, 5, 0, 0", render=False)
    with pytest.raises(ConfigError, match=r"reaches -6\.6 mm above the table") as err:
        check_board_above_table(s, sim_setup(s))
    assert "board_pose = [-400.0, -250.0, 12.6, 5.0, 0.0, 0.0]" in str(err.value.fix)
    for pose in ("-400, -250, 3, 0, 0, 20", "-400, -250, 0.2, 0, 0, 20"):
        s = scenario(pose)
        check_board_above_table(s, sim_setup(s))
    make_kinematic_robot(scenario("-400, -250, 0, 0, 0, 20", render=False))
