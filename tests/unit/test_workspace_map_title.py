"""``figures/workspace_accuracy.png``'s title is the report's accuracy line, which on real data
runs past 300 characters (session 25's new-user trip: the photoneo set's map showed its middle
alone, "82 mm at its edge; orientation within ... (farther from the calibration", cut at both
sides)."""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel, workspace_sample
from selfcal.plots.plotting import figure_problems
from selfcal.plots.workspace_map import workspace_map_figure
from selfcal.robot.definition import load_robot

LINE = (  # `selfcal report` of the photoneo set's calibration (docs/real-data.md's commands)
    "tool point within 6.734 mm (95 %) inside the calibrated region, 28.882 mm at its edge; "
    "orientation within 1.1305 deg, 2.5850 deg at the edge; the model error is not measured at "
    "31% of the edge's points, "
    "100% of the workspace's points (farther from the calibration postures than the "
    "cross-validation reached: held at its value there)"
)


def test_the_workspace_maps_long_title_is_whole():
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    p = 6
    em = ToolErrorModel(model, np.eye(4), np.arange(p), np.eye(p) * 1e-8, 1e-4)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    q_cal = lo + (hi - lo) * np.random.default_rng(0).uniform(0.4, 0.6, (12, robot.n))
    sample = workspace_sample(q_cal, robot.limits, count=32)
    fig = workspace_map_figure(em, sample, q_cal, LINE, "board frame")
    assert figure_problems(fig) == []
