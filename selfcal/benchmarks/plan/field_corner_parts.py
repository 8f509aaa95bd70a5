"""``python -m selfcal.benchmarks.plan.field_corner_parts [--robot kr6-r900] [--set "plan 12"]
[--seeds 1,2,3]``: which part of the rendered corners' error the field route's tool point feels
(issue #30: the rendered field draws err 2 - 10 times less than the forecast at the corner
noise measured against the truth; docs/plan.md, "What the rendered draws gain over the
forecast").

One set of :mod:`selfcal.benchmarks.plan.field_compare`'s rendered cell (``--robot``'s arm,
the plan made for 0.1 px with clear views, or the random 30), rendered for each seed of
``--seeds`` (its arm and image noise, as the table's draws are) and its markers detected by the
field route. Every detected marker's four corners against their true projections at the frame's
true camera pose give its errors ``E`` (4, 2) px; the route then calibrates (one-step, on the
analytic path: the corners written as a detections dataset, so each variant's corners are used
as given) the true projections plus:

- ``rendered``: ``E`` (the rendered draw's own corners, first detection pass; markers with a
  corner beyond the route's outlier floor left out, :func:`corner_errors_of`);
- ``exact``: nothing (the route's error without corner noise: the model's bias);
- ``centres``: each marker's mean error on all four of its corners;
- ``shapes``: ``E`` less that mean (the corners moved against each other);
- ``shuffled``: the values of ``E`` dealt to the corners at random (their spread kept, any
  pattern among a marker's corners or between views lost);
- ``white``: independent Gaussian noise of ``E``'s RMS per coordinate.

Per variant the median over the seeds of the tool-point error (the validation postures' RMS
after the best rigid alignment, as the table's draws) and of the one-step fit's own noise
estimate; beside them the corners' RMS and the forecast at it, and the marker centres' and
shapes' noise (:func:`selfcal.benchmarks.corner_noise.marker_centre_sigma`,
:func:`~selfcal.benchmarks.corner_noise.marker_shape_sigma`) and the forecast at them
(:func:`selfcal.calibration.field.bounds_split.split_tool_rms`).
Units: mm, px.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["VARIANTS", "corner_errors_of", "main", "variants"]

VARIANTS = ("rendered", "exact", "centres", "shapes", "shuffled", "white")
"""The corners each draw is calibrated on (module docstring)."""


def variants(E: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """``{name: errors (M, 4, 2) px}`` of :data:`VARIANTS` from the rendered markers' corner
    errors ``E`` (M, 4, 2) px (module docstring); ``rng`` draws the shuffle and the white
    noise."""
    E = np.asarray(E, dtype=float)
    centre = np.repeat(E.mean(axis=1, keepdims=True), 4, axis=1)
    flat = E.reshape(-1, 2)
    sigma = float(np.sqrt(np.mean(E**2)))
    return {"rendered": E, "exact": np.zeros_like(E), "centres": centre, "shapes": E - centre,
            "shuffled": flat[rng.permutation(len(flat))].reshape(E.shape),
            "white": rng.normal(0.0, sigma, E.shape)}  # fmt: skip


def corner_errors_of(root: Path) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
    """The markers the field route detects in the rendered one-camera field dataset ``root``
    whose four corners all lie within the route's outlier floor of the truth
    (:data:`selfcal.calibration.field.adjust.OUTLIER_FLOOR_PX`; a partly hidden marker's
    corners beyond it, which the route rejects, would otherwise swell every variant's noise but
    the rendered one's): ``(keys, true, E)``: (frame index, marker id) per marker, the true
    projections of its corners (M, 4, 2) px at the frame's true camera pose
    (``root/truth.json``) and the detected minus true corners ``E`` (M, 4, 2) px.

    Raises:
        InternalError: not a one-camera simulated field, or no marker detected.
    """
    from selfcal.calibration.field.adjust import OUTLIER_FLOOR_PX
    from selfcal.calibration.field.detections import detect_dataset
    from selfcal.errors import InternalError
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.sim.markers import MarkerField
    from selfcal.transforms import inv_pose

    ds = Dataset.open(root)
    truth = read_truth(root / "truth.json")
    if truth.marker_field is None or len(ds.info.cameras) != 1:
        raise InternalError(f"{root}: not a one-camera simulated field dataset")
    field = MarkerField.from_dict(truth.marker_field)
    corners = dict(zip(field.ids.tolist(), field.corners_world(), strict=True))
    keys, true, err = [], [], []
    for (index, _cam), found in sorted(detect_dataset(ds).detections.items()):
        frame = truth.frame(int(index))
        if frame is None:
            raise InternalError(f"{root}: truth.json has no frame {int(index)}")
        T = inv_pose(frame.T_world_cam_left)
        for mid, uv in sorted(found.items()):
            t = truth.intrinsics_left.project(corners[int(mid)] @ T[:3, :3].T + T[:3, 3])
            e = np.asarray(uv, dtype=float).reshape(4, 2) - t
            if np.linalg.norm(e, axis=1).max() > OUTLIER_FLOOR_PX:
                continue
            keys.append((int(index), int(mid)))
            true.append(t)
            err.append(e)
    if not keys:
        raise InternalError(f"{root}: no marker detected")
    return keys, np.array(true), np.array(err)


def _calibrated_on(render: Path, out: Path, keys: list, corners: np.ndarray) -> tuple[float, float]:
    """The one-step calibration of the rendered dataset ``render``'s postures from the marker
    ``corners`` (M, 4, 2) px of ``keys`` (written to ``out`` as a detections dataset): the
    tool-point error (mm, as the table's draws measure it) and the fit's noise estimate (px)."""
    from selfcal.calibration.field.calibrate import calibrate_detailed
    from selfcal.errors import InternalError
    from selfcal.io.dataset import Dataset, DatasetWriter
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.accuracy import aligned_errors, tool_tips

    ds = Dataset.open(render)
    cam = ds.info.cameras[0]
    by_frame: dict[int, dict[int, np.ndarray]] = {int(i): {} for i in ds.indices}
    for (index, mid), c in zip(keys, corners, strict=True):
        by_frame[index][mid] = c
    writer = DatasetWriter(out, dataclasses.replace(ds.info, observation="detections"))
    for index, q in zip(ds.indices, ds.joints_deg, strict=True):
        writer.add_frame(int(index), q, detections={cam: by_frame[int(index)]})
    shutil.copy(render / "truth.json", out / "truth.json")
    res = calibrate_detailed(out, method="joint", fair_nominal=False)
    truth = read_truth(out / "truth.json")
    qv = np.radians(ds.info.validation_joints_deg)
    true_tips = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    tip = aligned_errors(tool_tips(res.model, qv, truth.T_cam_tip), true_tips)["rms"]
    if res.joint is None:
        raise InternalError(f"{out}: the field route returned no joint refinement")
    return float(tip), float(res.joint.sigma_px)


def draw(path: Path, joints_deg: list, seed: int, work: Path) -> dict:
    """One seed of the set (scenario ``path``, postures ``joints_deg`` deg): rendered as the
    rendered table's draw ``seed`` is, and calibrated on each variant's corners. Returns the
    corners' RMS and centres' noise (px) and ``{variant: (tool mm, fit sigma px)}``."""
    from selfcal.benchmarks.corner_noise import marker_centre_sigma, marker_shape_sigma
    from selfcal.studies.montecarlo.run import acquire_draw

    render = work / f"render-{seed}"
    acquire_draw({"config": str(path), "poses": len(joints_deg), "pixel_sigma": 0.1,
                  "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
                  "joints_deg": joints_deg, "render": True}, render)  # fmt: skip
    keys, true, E = corner_errors_of(render)
    out: dict[str, object] = {"seed": seed, "sigma_px": float(np.sqrt(np.mean(E**2))),
           "centre_sigma_px": marker_centre_sigma(E),
        "shape_sigma_px": marker_shape_sigma(E), "markers": len(keys)}  # fmt: skip
    for name, V in variants(E, np.random.default_rng(seed)).items():
        out[name] = _calibrated_on(render, work / f"{name}-{seed}", keys, true + V)
    return out


def main(argv: list[str] | None = None) -> int:
    """Render, calibrate every variant, print the table."""
    from selfcal.benchmarks.plan.field_compare import field_sets, forecasts_at

    ap = benchmark_parser(
        __file__, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--robot", default="kr6-r900", help="the arm (default kr6-r900)")
    ap.add_argument("--set", default="plan 12", help='"plan 12" (default) or "random 30"')
    ap.add_argument("--seeds", default="1,2,3", help="the draws (default 1,2,3)")
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    rows = []
    with tempfile.TemporaryDirectory(prefix="selfcal-parts-") as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        root = Path(d)
        sets = field_sets(root, robot_name=a.robot, pixel_sigma_px=0.1, render=True)
        path, q, _ = sets[a.set]
        for s in seeds:
            rows.append(draw(path, q.tolist(), s, root))
            print(json.dumps(rows[-1]), flush=True)
        sigma = float(np.median([r["sigma_px"] for r in rows]))
        centre = float(np.median([r["centre_sigma_px"] for r in rows]))
        shape = float(np.median([r["shape_sigma_px"] for r in rows]))
        one = {a.set: sets[a.set]}
        fc = {"sigma": forecasts_at(root, a.robot, one, sigma)[a.set],
              "split": forecasts_at(root, a.robot, one, sigma, (centre, shape))[a.set]}  # fmt: skip
    lines = [f"\n{a.robot}, {a.set}, rendered seeds {a.seeds}: the corners' RMS {sigma:.4f} px "
             f"per coordinate, the marker centres' noise {centre:.4f} px and shapes' {shape:.4f} "
             f"px (medians); the forecast at the RMS {fc['sigma'] * 1000:.4f} mm, at the centres' "
             f"and shapes' {fc['split'] * 1000:.4f} mm",
             "", "| corners | tool-point error, median (mm) | / forecast at the RMS | "
             "/ forecast at the centres' and shapes' | fit's noise estimate, median (px) |",
             "|---|---|---|---|---|"]  # fmt: skip
    for name in VARIANTS:
        tip = float(np.median([r[name][0] for r in rows]))
        fit = float(np.median([r[name][1] for r in rows]))
        lines.append(f"| {name} | {tip:.4f} | {tip / (fc['sigma'] * 1000):.2f} | "
                     f"{tip / (fc['split'] * 1000):.2f} | {fit:.4f} |")  # fmt: skip
    lines.append(f"\n`uv run python -m selfcal.benchmarks.plan.field_corner_parts --robot {a.robot} "
                 f"--set '{a.set}' --seeds {a.seeds}`")  # fmt: skip
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
