"""NaN injection per estimator (issue #15): a NaN or infinity in the data or the model ends in
an InputError that says where it is, never a LinAlgError, an OverflowError or a silent NaN result.
(The solver's own NaN tests are in test_solver.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.identify import identify
from selfcal.calibration.tracker.identify import TrackerMeasurements, identify_tracker
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.ik_numeric import ToolTarget, solve_ik
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot


@pytest.fixture(scope="module")
def ur5e():
    robot = load_robot("ur5e")
    model = nominal_mcpc(robot)
    rng = np.random.default_rng(3)
    q = robot.home + rng.uniform(-0.5, 0.5, (20, robot.n))
    return robot, model, q, fk_tool(model, q)


def _nan_model(model):
    p = model.params.copy()
    p[1, 0] = np.nan
    return model.with_params(p)


@pytest.mark.parametrize("where", ["q", "T", "model"])
def test_identify(ur5e, where):
    _robot, model, q, T = ur5e
    q, T = q.copy(), T.copy()
    if where == "q":
        q[7, 2] = np.nan
    elif where == "T":
        T[4, 0, 3] = np.inf
    else:
        model = _nan_model(model)
    with pytest.raises(InputError, match=r"poses \[7\]|poses \[4\]|model holds NaN"):
        identify(model, q, T)


@pytest.mark.parametrize("where", ["q", "xyz", "R", "model"])
def test_tracker_identification(ur5e, where):
    _robot, model, q, T = ur5e
    q, xyz, R = q.copy(), T[:, :3, 3].copy(), T[:, :3, :3].copy()
    if where == "model":
        model = _nan_model(model)
    else:
        {"q": q, "xyz": xyz, "R": R}[where][3].flat[0] = np.nan
    with pytest.raises(InputError, match=where):
        identify_tracker(model, TrackerMeasurements(q, xyz, R))


@pytest.mark.parametrize("where", ["reference", "home", "limits", "model"])
def test_numerical_ik(ur5e, where):
    robot, model, q, T = ur5e
    target = ToolTarget.checked(T[0, :3, 3], T[0, :3, :3])
    kw = {"n_random": 2}
    limits = robot.limits.copy()
    if where in ("reference", "home"):
        kw[where] = np.full(robot.n, np.nan)
    elif where == "limits":
        limits[2, 1] = np.nan
    else:
        model = _nan_model(model)
    with pytest.raises(InputError, match=where if where != "limits" else "joint ranges"):
        solve_ik(model, limits, target, name="ur5e", **kw)
