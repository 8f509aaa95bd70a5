"""The board calibration's Cramer-Rao bounds describe the estimate that was run
(selfcal/calibration/board/bounds.py): the kinematic parameters free are the chosen candidate's
(selfcal/calibration/board/param_selection.py), not every minimal parameter; a held one has no
bound. Synthetic lab of tests/integration/synthetic_board.py, features projected analytically."""

from __future__ import annotations

import numpy as np
from synthetic_board import BOARD, CAMERA, ROBOT, make_lab
from synthetic_features import board_features

from selfcal.calibration.board.bounds import board_cramer_rao, to_minimal
from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.kinematics.mcpc import minimal_indices
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose


def _near_home(m: int) -> np.ndarray:
    """``m`` postures within a few degrees of home, where the camera sees the whole board."""
    rng = np.random.default_rng(3)
    return load_robot(ROBOT).home + rng.normal(0, np.radians(3.0), (m, 6))


def test_the_bounds_free_only_the_chosen_parameters():
    """With the placement and two joint offsets estimated, the minimal parameters those move
    have bounds, no larger than with every parameter free (fewer unknowns); the others were held
    and have none (before, every minimal parameter had a bound whatever was estimated)."""
    lab = make_lab(0)
    q = _near_home(8)
    feats = board_features(lab.true_model, lab.T_world_board, q, 0.2, 0)
    model = lab.true_model.with_base(inv_pose(lab.T_world_board))  # world = the board
    full = board_cramer_rao(BOARD, [CAMERA], model, q, [feats], 0.2)
    n = model.n
    chosen = board_cramer_rao(BOARD, [CAMERA], model, q, [feats], 0.2,
                              free_idx=placement_indices(n), offset_joints=[1, 2])  # fmt: skip
    assert full.estimated is None and chosen.estimated is not None
    got, every = chosen.parameter_std(), full.parameter_std()
    assert 0 < len(got) < len(every), sorted(got)
    assert {f"lx{n}", f"lz{n}", "alpha0"} <= set(got)  # the placement's
    assert f"lx{n - 2}" not in got  # an inner length no offset moves: held
    for name, s in got.items():
        assert s <= every[name] * (1 + 1e-6), (name, s, every[name])
    held = ~chosen.estimated
    assert np.all(chosen.covariance[held] == 0.0)


def test_the_minimal_parameters_map_to_themselves():
    """The map from the estimated parameters to the stored model's minimal ones (the gauge with
    the nominal's offsets) is the identity when the estimated ones are the minimal ones."""
    lab = make_lab(0)
    model = lab.true_model.with_base(inv_pose(lab.T_world_board))
    idx = minimal_indices(model.joint_types)
    poses = KinematicPoses(model, _near_home(3), idx, np.zeros((0, 4, 4)))
    np.testing.assert_allclose(to_minimal(poses), np.eye(idx.size), atol=1e-7)
