"""A field draw whose calibration detects the markers again through the estimated lens: the
Monte Carlo's bounds must use those detections, not a plain detection of the images (which may
hold other corners: a rendered KR6 field plan's draws crashed in 5 of 60 with "operands could
not be broadcast together with shapes (664,) (660,)" before the calibration handed its own
detections on, :attr:`selfcal.calibration.field.results.CalibrationOutput.observations`).

Slow: 12 rendered postures and a field calibration (~4 s idle); the draw is the one that crashed
(session 22's rendered field Monte Carlo, ``selfcal.benchmarks.plan.field_compare --robot
kr6-r900 --render --pixel-sigma 0.1``, plan 12, seed 4)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.benchmarks.plan.field_compare import FIELD
from selfcal.cli.plan_scenario import scenario_text
from selfcal.io.camera_file import camera_from_fov
from selfcal.io.plan_files import joints_csv
from selfcal.studies.montecarlo.run import draw_one

pytestmark = pytest.mark.slow

PLAN_DEG = [
    [15.874804, -81.340311, 99.022900, 18.699914, 81.582274, 12.865848],
    [13.760556, -63.114063, 114.200336, 32.867316, 55.753368, 40.168703],
    [26.322605, -63.658863, 126.980639, 59.086652, 26.551550, 117.543157],
    [10.485582, -82.190154, 125.935354, 34.961243, 47.211059, 128.883893],
    [33.889307, -69.712072, 98.182142, 15.868479, 76.660518, 140.006794],
    [35.189882, -68.952582, 113.573206, 18.748752, 77.022815, 101.096844],
    [59.538516, -69.428067, 123.319768, -20.253645, 30.400826, 82.446702],
    [58.333120, -78.257613, 123.124143, -53.295364, 47.135235, 21.778720],
    [55.038644, -62.117544, 109.160228, -24.462312, 69.104604, -6.577349],
    [26.743123, -86.811005, 99.348338, 17.875108, 52.281988, -97.148210],
    [52.606361, -77.952514, 123.125496, -11.567987, 45.084106, -116.549570],
    [49.956785, -65.266181, 127.343336, -15.873045, 39.099911, -140.104522],
]


def test_the_bounds_of_a_rendered_field_draw_use_the_calibrations_detections(tmp_path):
    camera = camera_from_fov(60.0, 640, 480)
    config = tmp_path / "scenario.toml"
    (tmp_path / "joints.csv").write_text(joints_csv(np.radians(PLAN_DEG), np.full(6, np.pi / 180)))
    config.write_text(scenario_text("kr6-r900", camera, None, len(PLAN_DEG), field=FIELD))
    row = draw_one({"config": str(config), "poses": len(PLAN_DEG), "pixel_sigma": 0.1,
                    "seed": 4, "traj_seed": 1, "perturb_seed": 4, "dither": True,
                    "joints_deg": PLAN_DEG, "render": True})  # fmt: skip
    assert row["status"] == "ok", row["status"]
    assert row["frames_used"] == row["frames"] == len(PLAN_DEG)
    assert np.isfinite(row["bound_tip_rms_mm"]) and row["bound_tip_rms_mm"] > 0
