"""``python -m selfcal.benchmarks.plan.field_forecasts [--robots ur5e,kr6-r900,er4u-paper]
[--pixel-sigma 0.1] [--candidates 400] [--write-docs]``: a field plan of 12 against the random 30 by forecast
only, per arm, with and without ``--clear-views`` (docs/plan.md, "What limits a field plan of
12"; issue #30).

The cells of :mod:`selfcal.benchmarks.plan.field_compare` (each arm with the 60 deg 640 x 480
wrist camera and the 20-marker field where its home posture looks; ``clear_views`` as
``field_compare --render`` plans, or not, as ``selfcal plan`` does by default), planned for
``--pixel-sigma``'s corner noise: the plan of 12's forecast
(:func:`selfcal.calibration.field.plan.plan_field`, the least of its choices), the choice it is
and the candidates it chose from, beside the forecast of the random 30 (the first 30 of the same
candidate sequence, drawn without the views' checks) and the count whose plan reaches it
(``selfcal plan``'s advice; "none" when no plan of up to 30 from those candidates does);
``--candidates`` the random candidates before the checks (the cells' 400). No draw, no
rendering. Units: mm.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from selfcal.benchmarks.doc_blocks import ROOT
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["main"]

DOCS = ROOT / "docs/plan.md"
BLOCK = "benchmark_plan_field_forecasts"


def _row(robot_name: str, clear: bool, pixel_sigma_px: float, candidates: int) -> str:
    """One cell's table row (module docstring)."""
    from selfcal.benchmarks.plan.field_compare import field_cell
    from selfcal.calibration.field.plan import MATCH_RANDOM, field_forecast, plan_field, random_plan

    with tempfile.TemporaryDirectory() as d:
        cell = field_cell(Path(d), robot_name, pixel_sigma_px, clear)
    setup, layout, ws, kw = cell["setup"], cell["layout"], cell["workspace"], cell["plan_kw"]
    kw = {**kw, "candidates": candidates}
    plan = plan_field(setup, 12, layout, ws, **kw)
    got = min(v for v in plan.choices.values() if v is not None)
    q30 = random_plan(setup, MATCH_RANDOM, seed=kw["seed"])
    r30 = field_forecast(setup, layout, q30, ws, pixel_sigma_px=pixel_sigma_px,
                         joint_sigma=cell["joint_sigma"]).tool_rms_m  # fmt: skip
    if r30 is None:
        return (
            f"| {robot_name} | {'yes' if clear else 'no'} | {got * 1000:.4f} | no bound | - | - |"
        )
    advice = "reaches it" if got <= r30 else (
        "none" if plan.to_match is None else str(plan.to_match[0]))  # fmt: skip
    return (f"| {robot_name} | {'yes' if clear else 'no'} | {got * 1000:.4f} ({plan.chosen_by}, "
            f"{plan.candidates} candidates) | {r30 * 1000:.4f} | {got / r30:.2f} | {advice} |")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Print (and with ``--write-docs`` write) the table."""
    from selfcal.benchmarks.doc_blocks import print_table

    ap = benchmark_parser(__file__, description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument(
        "--robots", default="ur5e,kr6-r900,er4u-paper", help="the arms (comma-separated)"
    )
    ap.add_argument("--pixel-sigma", type=float, default=0.1,
                    help="the corner noise the plans and the forecasts assume (px; default 0.1)")  # fmt: skip
    ap.add_argument("--candidates", type=int, default=400,
                    help="the random candidates each plan chooses from (default 400, the cells')")  # fmt: skip
    ap.add_argument("--write-docs", action="store_true", help="write the table into the docs")
    a = ap.parse_args(argv)
    lines = ["| arm | clear views | plan of 12: forecast (mm; chosen by, from) | random 30 (mm) | "
             "plan / random | the count that reaches it |", "|---|---|---|---|---|---|"]  # fmt: skip
    for robot in a.robots.split(","):
        for clear in (False, True):
            lines.append(_row(robot, clear, a.pixel_sigma, a.candidates))
            print(lines[-1], flush=True)
    lines.append(f"\n`uv run python -m selfcal.benchmarks.plan.field_forecasts --robots {a.robots} "
                 f"--pixel-sigma {a.pixel_sigma:g} --candidates {a.candidates} --write-docs`")  # fmt: skip
    return print_table("\n".join(lines), DOCS, BLOCK, write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
