"""A scenario with [target] board_pose: the random planner keeps the board where it is in view."""

from __future__ import annotations

import numpy as np

from selfcal.acquisition.backends import planning_inputs, sim_setup
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
