"""The public API (docs/api.md) on the repository's own real recording: a Nachi MZ25 with an
eye-in-hand camera and a 11 x 8 chessboard (tests/data/real/nachi-2025-01-17-photoneo, 24
images in 6 groups of 4 postures). Groups 1-5 calibrate, group 6 is held out, as the set's
independent reference splits it.

    uv run python examples/api_example.py [OUT_DIR]

OUT_DIR (default: a temporary folder) receives the two dataset folders ``cal`` and ``held``
and ``cal/calibration.json``; ``selfcal.evaluate`` writes nothing (``selfcal evaluate cal held
--out cal/evaluation.json`` keeps the check where ``selfcal report`` and ``export`` read it).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import selfcal

SET = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "nachi-2025-01-17-photoneo"
IMAGES = SET / "handeye_data" / "2025-01-17_data_photoneo"
ROBOT = SET / "inputs" / "nachi_mz25.urdf"


def run(out: Path) -> tuple[selfcal.BoardCalibrationResult, selfcal.Evaluation]:
    """Import both splits into ``out``, calibrate ``out/cal``, evaluate it on ``out/held``;
    returns the calibration and the held-out evaluation."""
    robot = selfcal.load_robot(ROBOT)  # a URDF alone loads: base link = root, tool = leaf
    print(f"{robot.name}: {len(robot.joint_names)} joints {robot.joint_types}")

    splits = {
        "cal": ("group[1-5]/*.png", "joints_calib.csv"),
        "held": ("group6/*.png", "joints_heldout.csv"),
    }
    for name, (pattern, joints) in splits.items():
        cameras = [selfcal.CameraImages.parse(f"cam0={IMAGES / pattern}")]
        info = selfcal.import_dataset(str(ROBOT), cameras, SET / "inputs" / joints, "rad",
                                      SET / "inputs" / "target.toml", out / name, link=True)  # fmt: skip
        print(f"{name}: {len(info.planned_joints_deg)} frames imported")

    print(f"route: {selfcal.dataset_route(out / 'cal')}")  # board: joints + a known board
    ds = selfcal.open_dataset(out / "cal")
    assert isinstance(ds, selfcal.Dataset)
    print(
        f"{len(ds.indices)} frames; joint readings of the first (deg): {ds.joints_deg[0].round(3)}"
    )

    cal = selfcal.calibrate(out / "cal")  # writes out/cal/calibration.json
    assert isinstance(cal, selfcal.BoardCalibrationResult)
    cam = cal.cameras[0]
    print(f"calibrated {cal.frames_used}/{cal.frames} frames: fit {cal.reprojection_rms_px:.3f} px, "
          f"fx {cam.fx:.1f} px, model {cam.model_name}")  # fmt: skip

    ev = selfcal.evaluate(out / "cal", out / "held")  # group 6 from its joint readings alone
    assert isinstance(ev, selfcal.Evaluation)
    print(f"held out: nominal {ev.rms['nominal']:.3f} px, calibrated {ev.rms['calibrated']:.3f} px")

    back = selfcal.read_calibration(out / "cal")  # what another program reads
    assert isinstance(back, selfcal.BoardCalibrationResult)
    print(f"read back: {back.reprojection_rms_px:.3f} px, robot {back.robot_model}")
    return cal, ev


if __name__ == "__main__":
    if len(sys.argv) > 1:
        run(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            run(Path(tmp))
