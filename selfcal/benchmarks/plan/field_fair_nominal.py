"""``python -m selfcal.benchmarks.plan.field_fair_nominal [--set 'random 30'] [--draws 5]``: why
the field's fair nominal errs more at the tool point than the drawn chain with nothing fitted
(docs/plan.md, "A marker field"; issue #30).

The draws of :mod:`selfcal.benchmarks.plan.field_compare` (its cell, its posture sets, the draw
``s`` = ``[perturbation] seed`` and noise seed, analytic, calibrated by the field route), each
replayed and compared with its truth at the 20 validation postures (the tool point: the flange
centre, the tool-tip RMS after the best rigid alignment, as the Monte Carlo measures it), for
three models that share the robot file's chain and differ only in the hand-eye (the rigid
alignment removes the base):

- ``drawn``: the chain as drawn, its hand-eye the drawing's (nothing fitted);
- ``fair``: the fair nominal (:mod:`selfcal.calibration.field.nominal_fit`: the hand-eye, the
  camera and the markers' corners fitted to the calibration's pixels);
- ``true poses``: the hand-eye fitted to the simulator's true camera poses at the calibration
  postures (:func:`selfcal.calibration.field.nominal_fit.place_nominal`, the pose distance: what
  a perfect camera stage would give the nominal chain).

Beside them: each hand-eye's distance from the true mount (mm, deg) and the fair nominal's
focal length and aspect ratio against the truth. Units: mm, deg, px.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["main"]


def _mount_error(T_true: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """(mm, deg) between two hand-eyes (flange -> camera, m)."""
    from selfcal.transforms import inv_pose

    D = inv_pose(T_true) @ T
    c = np.clip((np.trace(D[:3, :3]) - 1) / 2, -1.0, 1.0)
    return 1000 * float(np.linalg.norm(D[:3, 3])), float(np.degrees(np.arccos(c)))


def one_draw(config: Path, joints_deg: np.ndarray, seed: int) -> dict:
    """One draw of the posture set (``config`` its replay scenario, ``joints_deg`` (m, n)): the
    three models' tool-point RMS (mm), the hand-eyes' distances from the true mount and the fair
    nominal's camera errors (module docstring)."""
    from selfcal.calibration.field.calibrate import calibrate_detailed
    from selfcal.calibration.field.nominal_fit import place_nominal
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.accuracy import aligned_errors, tool_tips
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot
    from selfcal.studies.montecarlo.run import acquire_draw

    with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        root = Path(d) / "run"
        acquire_draw({"config": str(config), "poses": len(joints_deg), "pixel_sigma": 0.5,
                  "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
                  "joints_deg": np.asarray(joints_deg).tolist()}, root)  # fmt: skip
        out = calibrate_detailed(root, method="joint")
        ds = Dataset.open(root)
        truth = read_truth(root / "truth.json")
    robot = load_robot(ds.info.robot_model)
    qv, qc = np.radians(ds.info.validation_joints_deg), np.radians(ds.joints_deg)
    frames = {f.frame_index: f for f in truth.frames}
    T_cam = np.stack([frames[int(i)].T_world_cam_left for i in ds.indices])
    posed = place_nominal(nominal_mcpc(robot).with_tool(robot.T_flange_cam), qc, T_cam).model
    fair, fair_model = out.result.nominal, out.result.nominal_model
    if fair is None or fair_model is None:
        raise SystemExit(f"draw {seed}: the fair nominal's fit failed")
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    models = {"drawn": truth.nominal_model, "fair": fair_model, "true poses": posed,
              "calibrated": out.model}  # fmt: skip
    row = {k: aligned_errors(tool_tips(m, qv, truth.T_cam_tip), p_true)["rms"]  # mm
           for k, m in models.items()}  # fmt: skip
    row["drawn mount"] = _mount_error(truth.T_flange_cam, truth.T_flange_cam_nominal)
    row["fair mount"] = _mount_error(truth.T_flange_cam, fair.hand_eye.T_flange_cam_m)
    row["fair fx"] = fair.intrinsics.fx - truth.intrinsics_left.fx
    row["fair mu"] = fair.intrinsics.mu - truth.intrinsics_left.mu
    return row


def main(argv: list[str] | None = None) -> int:
    """Draw and print one line per draw and the medians."""
    from selfcal.benchmarks.plan.field_compare import field_sets

    ap = benchmark_parser(__file__, description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--set", default="random 30", help="'plan 12' or 'random 30'")
    ap.add_argument("--draws", type=int, default=5, help="seeds 1 .. N")
    ap.add_argument("--out", default="runs/plan-field-fair-nominal")
    a = ap.parse_args(argv)
    sets = field_sets(Path(a.out))
    if a.set not in sets:
        ap.error(f"--set {a.set!r}: one of {sorted(sets)}")
    config, q_deg, _ = sets[a.set]
    rows = []
    for s in range(1, a.draws + 1):
        r = one_draw(config, q_deg, s)
        rows.append(r)
        print(f"{a.set} draw {s}: tool point RMS drawn {r['drawn']:.3f}, fair {r['fair']:.3f}, "
              f"true poses {r['true poses']:.3f}, calibrated {r['calibrated']:.3f} mm; hand-eye "
              "from the true: drawn %.2f mm %.3f deg, fair %.2f mm %.3f deg; fair fx %+.3f px, "
              "mu %+.2e" % (*r["drawn mount"], *r["fair mount"], r["fair fx"], r["fair mu"]),
              flush=True)  # fmt: skip
    med = {k: np.median([r[k] for r in rows]) for k in ("drawn", "fair", "true poses")}
    print(f"{a.set}, {a.draws} draws, median tool point RMS: drawn {med['drawn']:.3f}, fair "
          f"{med['fair']:.3f}, true poses {med['true poses']:.3f} mm; the fair nominal worse than "
          f"drawn in {sum(r['fair'] > r['drawn'] for r in rows)} of {len(rows)}, its hand-eye "
          f"farther from the true mount than the drawing's in "
          f"{sum(r['fair mount'][0] > r['drawn mount'][0] for r in rows)} (mm) and "
          f"{sum(r['fair mount'][1] > r['drawn mount'][1] for r in rows)} (deg)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
