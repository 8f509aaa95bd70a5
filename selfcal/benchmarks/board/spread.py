"""Benchmark: the board bootstrap's run-to-run spread (``selfcal calibrate --spread N``,
:mod:`selfcal.calibration.board.bootstrap`) against the covariance's predicted RMS error and the
folds' jackknife, on the analytic mono-charuco run (issue #29).

For every posture count of ``--poses`` the dataset ``selfcal run`` writes for
``scenarios/mono-charuco.toml`` with ``[noise] render = false`` and ``[trajectory] poses = P``
(no misfit: the chain is the scenario's) is acquired and calibrated once, in a scratch folder;
then for every seed of ``--seeds`` ``--refits`` bootstrap refits of resampled arm
configurations are made (on ``--jobs`` worker processes) and their spread taken, the model
selection held (every refit fits the calibration's chosen kinematic parameters: what
``--spread N`` does) or, with ``--selection free``, each refit running its own selection (the
spread as it was measured before the selection was held). Per row: the bootstrap's RMS spread
over the regions inside / edge / workspace (mm), its ratio to the predicted RMS error and to
the jackknife's RMS spread, the refits that fitted other parameters than the calibration
(held: some the resample could not determine; free: another candidate chosen) and those that
failed; under the table per posture count the predicted RMS, the jackknife and the
calibration's true tool-point error at the validation postures. The rows are stamped with the
code that measured them (:func:`selfcal.benchmarks.doc_blocks.code_version`).

Run: ``MUJOCO_GL=egl uv run python -m selfcal.benchmarks.board.spread [--poses 15,30]
[--seeds 1,2,3] [--refits 20] [--selection held|free] [--jobs 1] [--write-docs]``
(``--write-docs``: the held table in docs/tool-accuracy.md, between the ``benchmark_board_spread``
markers; about 2 s of CPU per refit on 15 postures, idle).
"""

from __future__ import annotations

import contextlib
import json
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path

from selfcal.benchmarks.doc_blocks import ROOT, code_version, print_table
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
from selfcal.config.scenario import load_scenario
from selfcal.console.progress import TaskCounts
from selfcal.pipeline.board_spread import BootstrapRun, run_bootstrap, serial_runner
from selfcal.pipeline.run import run_all

SCENARIO = ROOT / "scenarios" / "mono-charuco.toml"
DOCS = ROOT / "docs" / "tool-accuracy.md"
BLOCK = "benchmark_board_spread"
REGIONS = ("inside", "edge", "workspace")


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",") if v.strip()]


def _runner(jobs: int) -> Callable[..., Iterable[tuple[int, dict]]]:
    """The refits on ``jobs`` worker processes (1: in this process)."""
    if jobs == 1:
        return serial_runner

    def run(fn: Callable[[dict], dict], items: list[dict],
            counts: TaskCounts) -> Iterable[tuple[int, dict]]:  # fmt: skip
        from selfcal.studies.parallel import run_tasks

        return run_tasks(fn, items, jobs=jobs, counts=counts,
                         error_row=lambda _i, exc: {"failed": f"{type(exc).__name__}: {exc}"})  # fmt: skip

    return run


def _mm(block: dict, key: str) -> list[float]:
    return [block["regions"][r][key] for r in REGIONS]


def measure(poses: int, seeds: list[int], refits: int, held: bool, jobs: int,
            scratch: Path) -> tuple[list[str], str]:  # fmt: skip
    """The table rows of one posture count and the sentence under the table."""
    out = scratch / f"poses{poses}"
    s = load_scenario(SCENARIO, {"noise": {"render": False}, "trajectory": {"poses": poses}})
    with warnings.catch_warnings(), contextlib.redirect_stdout(sys.stderr):
        warnings.simplefilter("ignore")  # the calibration's warnings are no finding here
        run_all(s, out, quiet=True, figures=False)  # its summary: not the table's
        cal = calibrate_board_dataset_detailed(out)
    acc = cal.result.accuracy
    if acc is None or acc.get("spread") is None:
        raise SystemExit(f"{out}: the calibration has no predicted accuracy or jackknife")
    predicted = [acc["regions"][r]["position_rms_mm"] for r in REGIONS]
    jack = _mm(acc["spread"], "spread_mm_rms")
    report = json.loads((out / "report.json").read_text())
    true = report["validation"]["tool_tip_error_mm"]["calibrated"]["rms"]
    rows = []
    for seed in seeds:
        run = BootstrapRun(refits, seed, _runner(jobs), held=held)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            block = run_bootstrap(cal, run, quiet=True).to_json()
        if "inside" not in block["regions"]:
            rows.append(f"| {poses} | {seed} | {refits} | no spread: {block['failed']} failed | "
                        f"- | - | - | {block['failed']} |")  # fmt: skip
            continue
        got = _mm(block, "spread_mm_rms")
        rows.append(
            f"| {poses} | {seed} | {block['resamplings']} | "
            + " / ".join(f"{v:.3f}" for v in got) + " | "
            + " / ".join(f"{g / p:.2f}" for g, p in zip(got, predicted, strict=True)) + " | "
            + " / ".join(f"{g / j:.2f}" for g, j in zip(got, jack, strict=True)) + " | "
            + f"{block.get('refits_other_parameters', '-')} | {block['failed']} |"
        )  # fmt: skip
        print(rows[-1], file=sys.stderr, flush=True)  # as it comes: a long run's progress
    sel = cal.fit.selection
    if sel is None:
        raise SystemExit(f"{out}: the calibration has no parameter selection")
    note = (f"{poses} postures ({sel.configurations} configurations, the calibration fits "
            f"{len(sel.identified)} kinematic parameters): predicted RMS error "
            + " / ".join(f"{v:.3f}" for v in predicted) + " mm, jackknife "
            + " / ".join(f"{v:.3f}" for v in jack)
            + f" mm, true tool-point error {true:.3f} mm RMS at the validation postures.")  # fmt: skip
    return rows, note


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", default="15,30", help="posture counts, comma separated")
    ap.add_argument("--seeds", default="1,2,3", help="the resamples' seeds, comma separated")
    ap.add_argument("--refits", type=int, default=20)
    ap.add_argument("--selection", choices=("held", "free"), default="held")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--write-docs", action="store_true",
                    help="write the table into docs/tool-accuracy.md (held selection only)")  # fmt: skip
    args = ap.parse_args(argv)
    held = args.selection == "held"
    if args.write_docs and not held:
        raise SystemExit("--write-docs writes the held selection's table; leave out --selection")
    code = code_version()
    lines = [
        "| postures | seed | refits | bootstrap RMS inside / edge / workspace (mm) | "
        "x predicted RMS | x jackknife RMS | refits with other parameters | failed |",
        "|---|---|---|---|---|---|---|---|",
    ]
    notes = []
    with tempfile.TemporaryDirectory(prefix="board-spread-") as tmp:
        for poses in _ints(args.poses):
            rows, note = measure(poses, _ints(args.seeds), args.refits, held, args.jobs, Path(tmp))
            lines += rows
            notes.append(note)
    selection = ("model selection held" if held
                 else "each refit with its own parameter selection")  # fmt: skip
    lines += ["", *notes, "",
              f"Selection: {selection}. Measured by the code at {code or 'an unknown commit'} "
              f"(`python -m selfcal.benchmarks.board.spread --poses {args.poses} --seeds "
              f"{args.seeds} --refits {args.refits} --selection {args.selection}`)."]  # fmt: skip
    return print_table("\n".join(lines), DOCS, BLOCK, write=args.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
