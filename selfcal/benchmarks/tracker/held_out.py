"""Benchmark: the tracker route's k-fold held-out RMS against the fair nominal's (issue #29).

Monte Carlo on simulated ER-4u positions (:mod:`selfcal.benchmarks.tracker.sim`), 0.1 mm noise
per coordinate, joints uniform over their ranges (at most +-170 deg), ``--draws`` draws per case
(seeds 1..draws):

- ``off its drawing``: every minimal parameter moved within +-1 mm / +-0.2 deg (the model fits);
- ``joint 2 bends``: the same with joint 2 bending by 0.05 deg x cos(q2 + q3), which no constant
  chain expresses (:data:`selfcal.sim.compliance.SHOULDER`);
- ``built to its drawing``: no kinematic error, only the tracker frame and the tool unknown (the
  calibration's further parameters can only fit the noise).

Each draw is calibrated as ``selfcal identify`` does (:func:`selfcal.calibration.tracker.cross_validation.fit_folds`
and :func:`selfcal.calibration.tracker.cross_validation.cross_validate`): the table gives the held-out
RMS of the calibration and of the fair nominal over the folds, the calibration's against
``sqrt(3) sigma sqrt(1 + p / n)`` (the held-out RMS of a least-squares fit that fits: ``p``
estimated parameters, ``n`` the equations a fold is fitted to), and in how many draws the
calibration is said to be NO GAIN (not better than the fair nominal held out). Then the lines
``selfcal identify`` prints for draw 1 of two cases (the measurements written to a file, the
command run on it).

Run: ``uv run python -m selfcal.benchmarks.tracker.held_out [--draws 30] [--write-docs]``
(rewrites the blocks in docs/tool-accuracy.md and docs/tracker.md).
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, print_table, write_block
from selfcal.benchmarks.tracker.sim import TrackerCase, make_case
from selfcal.benchmarks.usage import benchmark_parser, module_command
from selfcal.calibration.identify import IdentificationWarning
from selfcal.calibration.tracker.cross_validation import cross_validate, fit_folds
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot
from selfcal.sim.compliance import SHOULDER
from selfcal.threads import limit_threads

__all__ = ["CASES", "draw", "run", "table", "example", "main"]

ROBOT = "er4u-paper"
SIGMA_M = 1e-4
CASES = (
    ("off its drawing", 30, 1.0, False),
    ("joint 2 bends", 30, 1.0, True),
    ("built to its drawing", 30, 0.0, False),
    ("built to its drawing", 15, 0.0, False),
)
"""(case, rows, parameter error in mm (and a fifth of it in deg), joint 2 bends)."""
EXAMPLES = (0, 3)
"""The cases whose draw 1 :func:`example` runs through ``selfcal identify``."""
DOCS = ((ROOT / "docs" / "tool-accuracy.md", "benchmark_tracker_held_out"),
        (ROOT / "docs" / "tracker.md", "tracker_held_out_example"))  # fmt: skip
KEEP = ("fit RMS", "nominal fit RMS", "cross-validated", "no cross-validation", "predicted:")
"""The lines of ``selfcal identify``'s output :func:`example` shows."""


def _simulate(case_index: int, seed: int) -> tuple[TrackerCase, TrackerMeasurements]:
    """Draw ``seed`` of :data:`CASES`' case ``case_index``: the simulated robot and its
    measured positions (m)."""
    _, rows, err_mm, bends = CASES[case_index]
    case = make_case(load_robot(ROBOT), seed=seed, translation_mm=err_mm, rotation_deg=err_mm / 5)
    q = case.configurations(rows, seed)
    q_true = SHOULDER.bent(q) if bends else q
    rng = np.random.default_rng(seed + 500)
    xyz = fk_tool(case.true, q_true)[:, :3, 3] + rng.normal(0.0, SIGMA_M, (rows, 3))
    return case, TrackerMeasurements(q, xyz, None, None, None, None)


def draw(case_index: int, seed: int) -> dict:
    """One draw: the held-out RMS (mm) of the calibration and the fair nominal, the
    calibration's against a fitting least-squares model's, and whether it is supported."""
    case, meas = _simulate(case_index, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        p = int(identify_tracker(case.nominal, meas, sigma_t_m=SIGMA_M).estimated.sum())
        folds = fit_folds(case.nominal, meas, sigma_t_m=SIGMA_M, sigma_r_rad=1e-4)
    cv = cross_validate(case.nominal, meas, folds, sigma_t_m=SIGMA_M, sigma_r_rad=1e-4)
    assert folds is not None and cv is not None
    n = 3 * meas.m * (folds.k - 1) / folds.k
    fitting = np.sqrt(3.0) * SIGMA_M * 1e3 * np.sqrt(1.0 + p / n)
    return {"rms_mm": cv.rms_mm, "nominal_mm": cv.nominal_rms_mm, "ratio": cv.rms_mm / fitting,
            "supported": cv.supported, "folds": cv.folds}  # fmt: skip


def run(draws: int = 30) -> list[dict]:
    """One row per case of :data:`CASES` over seeds 1..``draws``."""
    rows = []
    for i, (name, m, _, _) in enumerate(CASES):
        got = [draw(i, seed) for seed in range(1, draws + 1)]
        rows.append({"case": name, "rows": m, "draws": draws, "folds": got[0]["folds"],
                     **{k: np.array([g[k] for g in got], float)
                        for k in ("rms_mm", "nominal_mm", "ratio", "supported")}})  # fmt: skip
    return rows


def _median_range(v: np.ndarray, fmt: str) -> str:
    lo, mid, hi = np.percentile(v, [10, 50, 90])
    return f"{mid:{fmt}} ({lo:{fmt}}-{hi:{fmt}})"


def table(rows: list[dict]) -> str:
    """The Markdown table of :func:`run`'s rows."""
    head = (
        "| ER-4u, 0.1 mm | rows | folds | held-out RMS calibrated (mm), median (10-90 %) | "
        "fair nominal (mm) | calibrated / sqrt(3) sigma sqrt(1 + p/n): pooled, median "
        "(10-90 %) | NO GAIN said |\n|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['case']} | {r['rows']} | {r['folds']} | {_median_range(r['rms_mm'], '.3f')} | "
        f"{_median_range(r['nominal_mm'], '.3f')} | {np.sqrt(np.mean(r['ratio'] ** 2)):.2f}, "
        f"{_median_range(r['ratio'], '.2f')} | {int(np.sum(r['supported'] == 0))} of "
        f"{r['draws']} |"
        for r in rows
    ]
    note = (
        f"\n{rows[0]['draws']} draws per row (seeds 1-{rows[0]['draws']}); "
        f"`uv run {module_command(__file__)} --write-docs`."
    )
    return head + "\n".join(lines) + "\n" + note


def example(case_index: int) -> str:
    """``selfcal identify``'s lines (:data:`KEEP`) on draw 1 of :data:`CASES`' case
    ``case_index``, its measurements written to a file as the command reads them."""
    from selfcal.cli.main import main as selfcal

    _, meas = _simulate(case_index, 1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "measurements.csv"
        head = ",".join([f"j{i + 1}" for i in range(meas.q.shape[1])] + ["x_mm", "y_mm", "z_mm"])
        body = np.column_stack([np.degrees(meas.q), meas.xyz * 1e3])
        np.savetxt(path, body, fmt="%.6f", delimiter=",", header=head, comments="")
        out = io.StringIO()
        argv = ["identify", str(path), "--robot", ROBOT, "--joint-units", "deg",
                "--out", str(Path(tmp) / "tracker-cal")]  # fmt: skip
        with contextlib.redirect_stdout(out), warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            assert selfcal(argv) == 0
        text = out.getvalue().replace(str(Path(tmp) / "tracker-cal"), "tracker-cal")
    lines = [ln for ln in text.splitlines() if ln.startswith(KEEP)]
    name, rows, _, _ = CASES[case_index]
    return (f"$ selfcal identify measurements.csv --robot {ROBOT} --joint-units deg --out "
            f"tracker-cal    # {rows} positions, {name}\n" + "\n".join(lines))  # fmt: skip


def examples() -> str:
    """The fenced example of :func:`example`'s cases, with the command that writes it."""
    text = "\n\n".join(example(i) for i in EXAMPLES)
    return (f"```text\n{text}\n```\n\nSimulated (draw 1 of the table's cases, written to a file "
            f"and run through the command): `uv run {module_command(__file__)} --write-docs`.")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread) and print, or write, the table and the examples."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=30, help="draws per case (default 30)")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the blocks in docs/tool-accuracy.md and docs/tracker.md")  # fmt: skip
    args = ap.parse_args(argv)
    shown = examples()
    (doc, block), (doc2, block2) = DOCS
    print_table(table(run(args.draws)) + "\n\n" + shown, doc, block, write=args.write_docs)
    if args.write_docs:
        write_block(doc2, shown, block2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
