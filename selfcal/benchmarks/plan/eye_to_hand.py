"""``python -m selfcal.benchmarks.plan.eye_to_hand [--draws 20] [--out DIR]``: the postures of
``selfcal plan --mount eye-to-hand`` against random ones, achieved in simulation (docs/plan.md,
issue #30).

The cell of docs/plan.md's eye-to-hand example (UR5e, a 40 deg 640 x 480 camera still at
-1062, -133, 613 mm looking along the base's x axis, the ChArUco on the flange): the plan of 12,
the first 12 and the first 30 of its candidate pool (random postures under the same filters).
Every draw is one simulated truth (``[perturbation] seed`` = the draw: every minimal parameter,
the board's mount and the camera's placement in the chain included, within +-1 mm and
+-0.5 deg, the deviation the plan assumes) and one noise draw (0.5 px corners, quantised joint
read-back), acquired on the analytic path (``selfcal acquire``) and calibrated by the board route
as ``selfcal calibrate`` does; the achieved error is the RMS over the plan's 50 workspace
postures of the flange centre predicted by the calibrated chain (in the camera frame) against
the truth's, after the best rigid alignment: the quantity the plan predicts. Prints, per
posture set, the prediction, the achieved median and 90th percentile and their ratio.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["CAMERA_POSE", "achieved", "main", "posture_sets"]

CAMERA_POSE = np.array([-1062.0, -133.0, 613.0, -90.0, 0.0, -90.0])
"""mm, deg: docs/plan.md's still camera."""


def posture_sets(count: int = 12, random_counts: tuple[int, ...] = (12, 30)) -> dict:
    """``{"sets": {name: (q (m, n) rad, predicted tool-point RMS m)}, "setup", "workspace"}``:
    the plan of ``count`` and the pool's first ``random_counts`` postures
    (:func:`selfcal.benchmarks.plan.compare.sets_of`)."""
    from selfcal.benchmarks.plan.compare import sets_of
    from selfcal.calibration.board.plan.views import PlanSetup
    from selfcal.io.camera_file import camera_from_fov
    from selfcal.io.target_toml import load_board
    from selfcal.robot.definition import load_robot, models_dir
    from selfcal.target.placement import board_on_flange, camera_pose

    board = load_board(models_dir() / "targets/charuco.toml")
    T_bc = camera_pose(CAMERA_POSE[:3] / 1000.0, np.radians(CAMERA_POSE[3:]))
    setup = PlanSetup.eye_to_hand_setup(load_robot("ur5e"), camera_from_fov(40.0, 640, 480),
                                        board, T_bc, board_on_flange(board))  # fmt: skip
    return sets_of(setup, count, random_counts)


def achieved(setup, q: np.ndarray, qw: np.ndarray, seed: int, folder: Path) -> float:
    """The achieved tool-point RMS (m) over ``qw`` of the board route on the postures ``q``
    (m, n) rad for the truth and noise of ``seed`` (module docstring), acquired in a temporary
    folder under ``folder``; NaN when the calibration fails."""
    from selfcal.calibration.board.dataset import calibrate_board_dataset
    from selfcal.cli.main import main as selfcal
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.errors import SelfCalError
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.plan_files import joints_csv
    from selfcal.io.truth import read_truth
    from selfcal.pipeline.static_report import flange_centre_errors
    from selfcal.robot.definition import models_dir
    from selfcal.transforms import inv_pose

    robot = setup.robot
    with tempfile.TemporaryDirectory(dir=folder) as d:
        root = Path(d)
        shutil.copyfile(models_dir() / "targets/charuco.toml", root / "target.toml")
        write_text_atomic(root / "joints.csv", joints_csv(q, robot.edge_unit))
        text = scenario_text("ur5e", setup.camera, None, len(q), camera_pose=CAMERA_POSE,
                             seed=seed, pixel_sigma=0.5)  # fmt: skip
        text = text.replace("[noise]\n", f"[noise]\nseed = {seed}\n")
        write_text_atomic(root / "scenario.toml", text)
        if selfcal(["acquire", str(root / "scenario.toml"), "--out", str(root / "run"),
                    "--quiet"]) != 0:  # fmt: skip
            return float("nan")
        try:
            cal = calibrate_board_dataset(root / "run")
        except SelfCalError:
            return float("nan")
        truth = read_truth(root / "run/truth.json")
    assert truth.board is not None
    true_chain = truth.true_model.with_base(inv_pose(np.asarray(truth.board["T_world_cam"])))
    e = flange_centre_errors(cal.model, true_chain, truth.board["T_flange_board"], robot, qw)
    return e["rms"] / 1000.0


def main(argv: list[str] | None = None) -> int:
    """Draw and print the table."""
    import warnings

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--out", default="runs/plan-e2h-compare")
    a = ap.parse_args(argv)
    got = posture_sets()
    folder = Path(a.out)
    folder.mkdir(parents=True, exist_ok=True)
    print(f"ur5e eye-to-hand, {a.draws} draws")
    print("| postures | predicted (mm) | achieved median (mm) | 90th percentile | median / "
          "predicted | failed |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (q, pred) in got["sets"].items():
            e = np.array([achieved(got["setup"], q, got["workspace"], s, folder)
                          for s in range(1, a.draws + 1)])  # fmt: skip
            ok = e[np.isfinite(e)] * 1000
            med, p90 = np.median(ok), np.percentile(ok, 90)
            print(f"| {name} | {pred * 1000:.3f} | {med:.3f} | {p90:.3f} | "
                  f"{med / (pred * 1000):.2f} | {int((~np.isfinite(e)).sum())} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
