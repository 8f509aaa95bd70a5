"""``python -m selfcal.benchmarks.plan.add_pool [--truths 1,2,3] [--add 5] [--more 2]
[--jobs 1] [--write-docs]``: how far ``selfcal plan --add K`` can lower the predicted error of the eye-to-hand
benchmark's wrist-only datasets, forecast only (docs/plan.md, issue #30).

For each truth (seed) the dataset :func:`selfcal.benchmarks.plan.add.still_camera_row` records
(:data:`selfcal.benchmarks.plan.add.STILL_POSTURES` postures of one arm configuration) on the
benchmark's nominal cell, not calibrated: the cell as drawn, every feature seen, the placement
alone kept (what a calibration of one configuration keeps), planned with ``selfcal plan
--add``'s defaults (seed 1, 400 candidates, 0.5 px, the encoders' read-back noise, the default
deviation, the planning window's workspace). Rows, each a set of added postures: the plan of K
(the greedy's next :data:`selfcal.calibration.board.plan.add.SPARE` picks its spares); the same
with every candidate of the pool a spare (one pass of swaps over the whole pool, by the same
draws' RMS); the plans of K + 1 to K + ``--more``. Columns: the predicted tool-point RMS (mm)
before and after (the forecast's candidate, the first line of ``selfcal plan --add``), the
bound with every parameter kept (the selection's largest candidate at those postures), the
median and RMS of 400 draws of the arm and the noise with the selection deciding in each
(seed 1, as the command's sixth line), and the share of those draws keeping a smaller set.
``--write-docs`` puts the table, with the command and the code that measured it
(:func:`selfcal.benchmarks.doc_blocks.code_version`: a clean commit, or nothing is written),
between docs/plan.md's ``benchmark_plan_add_pool`` markers.
"""

from __future__ import annotations

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, code_version, print_table
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["pool_line", "pool_rows", "main"]

HEADER = (
    "| truth | added postures | predicted before -> after (mm), kept | all kept (mm) "
    "| draws' median (the first line's before over it), RMS (mm) | smaller set kept |\n"
    "|---|---|---|---|---|---|"
)
"""The table's header (:func:`pool_line` its rows)."""


def _dataset(seed: int):
    """The truth ``seed``'s wrist-only dataset on the nominal cell (module docstring): a
    :class:`selfcal.calibration.board.plan.add.DatasetPlan`."""
    from selfcal.benchmarks.plan.add import STILL_POSTURES, still_cell
    from selfcal.calibration.board.nominal_fit import placement_indices
    from selfcal.calibration.board.plan.add import DatasetPlan
    from selfcal.sim.static_camera import plan_static_postures

    setup, cell, _, _ = still_cell()
    q = plan_static_postures(cell, 1, STILL_POSTURES, seed=seed)
    ids = np.asarray(setup.board.layout()[0], np.int64)
    free = np.asarray(placement_indices(setup.robot.n), np.int64)
    return DatasetPlan(setup, q, tuple(ids for _ in q), free, np.zeros(0, np.int64))


def pool_rows(seed: int, add: int, more: int) -> list[dict]:
    """The rows of truth ``seed`` (module docstring), figures in mm."""
    from selfcal.calibration.board.plan.add import SPARE, plan_additions
    from selfcal.calibration.board.plan.ground import PlanOptions
    from selfcal.calibration.board.plan.information import board_model, frame_information
    from selfcal.calibration.board.plan.planner import predict_kept
    from selfcal.calibration.board.plan.spread import DRAWS, plan_spread
    from selfcal.estimation.joint_report import aligned_tool_weight, encoder_sigma

    plan = _dataset(seed)
    setup = plan.setup
    js = encoder_sigma(setup.robot)
    opts = PlanOptions(joint_sigma=js)
    model = board_model(setup)
    var = opts.deviation.variance(model.joint_types)
    ids = np.asarray(setup.board.layout()[0], np.int64)
    rows = []
    runs = [(f"plan of {add}", add, SPARE), (f"{add}, the whole pool spares", add, 10**9)]
    runs += [(f"plan of {k}", k, SPARE) for k in range(add + 1, add + more + 1)]
    for name, k, spare in runs:
        got = plan_additions(plan, k, opts, spare=spare)
        q_all = np.concatenate([plan.q, got.q])
        seen = [*plan.seen, *([ids] * len(got.q))]
        G = aligned_tool_weight(model, got.workspace, setup.T_tool_tip)
        F = frame_information(setup, q_all, opts.pixel_sigma_px, js, seen).sum(axis=0)
        bound = predict_kept(setup, q_all, F, G, var, got.forecast.kept_sets[-1])
        sp = plan_spread(setup, q_all, G, var, opts.pixel_sigma_px, js, plan.seen, draws=DRAWS,
                         seed=opts.seed)  # fmt: skip
        rows.append({"truth": seed, "set": name, "before": got.before_m * 1e3,
                     "after": got.after_m * 1e3, "kept": got.kept_after, "bound": bound * 1e3,
                     "median": sp.percentile(50) * 1e3,
                     "rms": float(np.sqrt(np.mean(sp.tool_m**2))) * 1e3,
                     "smaller": sp.smaller_share})  # fmt: skip
    return rows


def pool_line(r: dict) -> str:
    """One row of :func:`pool_rows` as a line of the table (figures in mm, ratios to the
    first line's before)."""
    return (f"| {r['truth']} | {r['set']} | {r['before']:.3f} -> {r['after']:.3f} "
            f"({r['before'] / r['after']:.2f} times), {r['kept']} | {r['bound']:.3f} "
            f"({r['before'] / r['bound']:.2f} times) | {r['median']:.3f} "
            f"({r['before'] / r['median']:.2f} times), {r['rms']:.3f} | "
            f"{100 * r['smaller']:.0f} % |")  # fmt: skip


def _rows(item: tuple[int, int, int]) -> list[dict]:
    return pool_rows(*item)


def main(argv: list[str] | None = None) -> int:
    """Run the truths and print the table."""
    from multiprocessing import get_context

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--truths", default="1,2,3", help="the truths' seeds, comma separated")
    ap.add_argument("--add", type=int, default=5)
    ap.add_argument("--more", type=int, default=2)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite docs/plan.md's benchmark_plan_add_pool block")  # fmt: skip
    a = ap.parse_args(argv)
    items = [(int(s), a.add, a.more) for s in a.truths.split(",")]
    code = code_version()
    with get_context("spawn").Pool(a.jobs) as pool:
        rows = [r for rs in pool.map(_rows, items) for r in rs]
    lines = [HEADER, *(pool_line(r) for r in rows), ""]
    by = f", measured by the code at {code}" if code else " (no git checkout: the code unknown)"
    lines.append(f"`python -m selfcal.benchmarks.plan.add_pool --truths {a.truths} --add {a.add} "
                 f"--more {a.more} --write-docs`{by}.")  # fmt: skip
    return print_table("\n".join(lines), ROOT / "docs" / "plan.md", "benchmark_plan_add_pool",
                       write=a.write_docs)  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
