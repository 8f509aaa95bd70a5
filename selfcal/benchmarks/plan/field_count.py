"""``python -m selfcal.benchmarks.plan.field_count [--counts 12,15,18,24] [--write-docs]``: what
limits a field plan of 12 against a random plan of 30 (docs/plan.md, "A marker field"; issue #30).

The cell of :mod:`selfcal.benchmarks.plan.field_compare` (UR5e, 60 deg 640 x 480 wrist camera,
the 20-marker field). For the plan of 12, the random plans of 12 and 30 (the first of the same
candidate sequence) and the plan of 30, each posture set's forecast
(:func:`selfcal.calibration.field.plan.field_forecast`: the markers' corners unknown, as the
field route estimates them) beside the same bound with the corners known (the planner's
criterion, :func:`selfcal.calibration.field.plan_information.frame_information` summed:
``sqrt(trace(G C))``) and the corners-unknown exchange's criterion
(:func:`selfcal.calibration.field.plan_corners.corner_criterion`: the corners unknown, each
posture's read-back errors eliminated over its own rows: the forecast, over the postures whose
view the route registers; until session 26 their coupling between markers was dropped), the
markers seen per view and the views per marker, and the unknowns (camera, kinematics, corners of the markers seen twice, the joints' read-back errors) against
the equations (two per corner seen). Then the plan's forecast for each of ``--counts``
postures (:func:`selfcal.calibration.field.plan.plan_field`; its ``to_match``, the count
``selfcal plan`` advises) against the random 30's, and the plan of 12 before the exchange with
the corners unknown (:mod:`selfcal.calibration.field.plan_corners`, the last of
:data:`selfcal.calibration.field.plan.CHOICES`): the best of the other choices. Forecasts only:
no draw, no rendering.
Units: mm, px.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["main"]

DOCS = ROOT / "docs/plan.md"
BLOCK = "benchmark_plan_field_count"


def _row(cell: dict, name: str, q: np.ndarray) -> str:
    """One posture set's table row (module docstring)."""
    from selfcal.calibration.board.plan.greedy import predicted_error
    from selfcal.calibration.field.bounds_setup import predicted_setup
    from selfcal.calibration.field.plan import field_forecast
    from selfcal.calibration.field.plan_corners import corner_blocks, corner_criterion
    from selfcal.calibration.field.plan_information import (
        frame_information,
        posture_rows,
        tool_weight,
    )
    from selfcal.camera import Visibility
    from selfcal.kinematics.forward import fk_tool

    setup, layout, js, ws = cell["setup"], cell["layout"], cell["joint_sigma"], cell["workspace"]
    fc = field_forecast(setup, layout, q, ws, pixel_sigma_px=0.5, joint_sigma=js)
    F = frame_information(setup.model_cam, setup.rig, q, layout, pixel_sigma_px=0.5,
                          joint_sigma=js)  # fmt: skip
    G = tool_weight(setup.model_cam, ws, setup.robot.T_flange_cam)
    n_cam = F.shape[1] - len(G)
    known = predicted_error(F.sum(axis=0), G, n_cam)
    fs = predicted_setup(setup.model_cam, q, setup.rig, layout.ids, layout.corners_world,
                         layout.normals_world, layout.scale_ids, layout.scale_length_m,
                         pixel_sigma_px=0.5, joint_sigma=js)  # fmt: skip
    crit = corner_criterion(corner_blocks(posture_rows(fs, setup.rig.n_cameras)), G,
                            np.arange(len(q)))  # fmt: skip
    vis = setup.rig.visible_markers(Visibility(), fk_tool(setup.model_cam, q),
                                    layout.corners_world, layout.normals_world)[:, 0]  # fmt: skip
    per_view, per_marker = vis.sum(axis=1), vis.sum(axis=0)
    corners = 3 * 4 * int((per_marker >= 2).sum())
    unknowns = (n_cam, len(G), corners, q.shape[1] * len(q))
    rms = "none" if fc.tool_rms_m is None else f"{fc.tool_rms_m * 1000:.3f}"
    return (f"| {name} | {rms} | {known * 1000:.3f} | {crit * 1000:.3f} | {fc.fx_std_px:.2f} | "
            f"{per_view.mean():.1f} ({per_view.min()} - {per_view.max()}) | "
            f"{per_marker.mean():.1f} ({per_marker.min()} - {per_marker.max()}) | "
            f"{' + '.join(map(str, unknowns))} = {sum(unknowns)} | {2 * fc.observations} |")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Print (and with ``--write-docs`` write) the two tables."""
    from selfcal.benchmarks.doc_blocks import print_table
    from selfcal.benchmarks.plan.field_compare import field_cell
    from selfcal.calibration.field.plan import CHOICES, field_forecast, plan_field, random_plan

    ap = benchmark_parser(__file__, description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--counts", default="12,15,18,24", help="the plans' sizes (comma-separated)")
    ap.add_argument("--write-docs", action="store_true", help="write the tables into the docs")
    a = ap.parse_args(argv)
    counts = [int(c) for c in a.counts.split(",")]
    with tempfile.TemporaryDirectory() as d:
        cell = field_cell(Path(d))
    setup, layout, ws, kw = cell["setup"], cell["layout"], cell["workspace"], cell["plan_kw"]
    plans = {n: plan_field(setup, n, layout, ws, **kw) for n in sorted({12, 30, *counts})}
    sets = {"plan 12": plans[12].q, "random 12": random_plan(setup, 12, seed=kw["seed"]),
            "random 30": random_plan(setup, 30, seed=kw["seed"]), "plan 30": plans[30].q}  # fmt: skip
    p12 = plans[12]
    assert p12.pool is not None and p12.chosen is not None
    if p12.start is not None:  # the other choices' best: where the corners' exchange began
        sets[f"plan 12 before the corners' exchange ({p12.start_by})"] = p12.pool[p12.start]
    lines = ["| postures | forecast (mm) | corners known (mm) | the exchange's criterion (mm) | "
             "fx bound (px) | markers per view, mean (range) | views per marker, mean (range) | "
             "unknowns: camera + kinematics + corners + read-back | equations |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    lines += [_row(cell, name, q) for name, q in sets.items()]
    f30 = field_forecast(setup, layout, sets["random 30"], ws, pixel_sigma_px=0.5,
                         joint_sigma=cell["joint_sigma"])  # fmt: skip
    r30 = f30.tool_rms_m
    if r30 is None:
        raise SystemExit(f"the random 30 postures have no forecast to compare with: {f30.why}")
    lines += ["", f"| plan of | forecast (mm) | chosen by | against the random 30's "
              f"{r30 * 1000:.3f} mm | `selfcal plan`'s advice |", "|---|---|---|---|---|"]  # fmt: skip
    for n in counts:
        p = plans[n]
        got = min(v for v in p.choices.values() if v is not None)
        advice = "-" if p.to_match is None else (
            f"a plan of {p.to_match[0]} ({p.to_match[1] * 1000:.3f} mm)")  # fmt: skip
        lines.append(f"| {n} | {got * 1000:.3f} | {p.chosen_by} | {got / r30:.2f} times | "
                     f"{advice} |")  # fmt: skip
    swaps = 0 if p12.start is None else len(set(p12.start) - set(p12.chosen))
    lines.append(f"\nThe plan of 12 is chosen by {p12.chosen_by}; the exchange with the corners "
                 f"unknown (`{CHOICES[-1]}`, `selfcal/calibration/field/plan_corners.py`) swapped "
                 f"{swaps} of the 12 postures of the best other choice.\n\n"
                 f"`uv run python -m selfcal.benchmarks.plan.field_count --counts {a.counts} "
                 "--write-docs`")  # fmt: skip
    return print_table("\n".join(lines), DOCS, BLOCK, write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
