"""Benchmark: does the predicted tool-point accuracy of a tracker calibration hold? (issue #29)

Monte Carlo on simulated analytic data (:mod:`selfcal.benchmarks.tracker.sim`): per robot, noise
level and model, ``--draws`` draws, each a new true chain (every minimal parameter moved within
+-1 mm / +-0.2 deg, a tool point and a tracker frame), 30 training positions uniform in the
central 70 % of each joint's range (within +-170 deg) with Gaussian noise, the calibration
(:func:`selfcal.calibration.tracker.identify.identify_tracker`) and its predicted accuracy
(:func:`selfcal.calibration.tracker.accuracy.tracker_accuracy`). The predicted 95 % bound and
RMS are compared with the true error (predicted tool point against the true chain's, no noise)
at the workspace sample's joint vectors (inside the calibrated region, at its edge, over the
joint limits: :mod:`selfcal.kinematics.tool_error`).

Models: ``fits`` (the true robot is a chain of the model's kind), ``compliance`` (joint 2
bends by 0.05 deg x cos(q2 + q3), which no constant chain expresses) and ``gear`` (an eccentric
gear, :func:`selfcal.sim.gear.draw_gear`: one joint, drawn per truth, turns ``A sin(theta +
phase)`` past its reading, ``A`` moving the tool about 0.2 mm, which no link table expresses).

Reported per row: coverage (the share of (draw, point) pairs whose true error is within the
predicted 95 % bound; target 90-98 %), the pooled ratio of the predicted to the true RMS (target
0.7-1.4) with the 10-90 % range of the per-draw ratios, and the same coverage for the covariance
alone (no model error).

Run: ``uv run python -m selfcal.benchmarks.tracker.accuracy [--draws 30] [--robots R,..]
[--models M,..] [--noise-mm S,..] [--write-docs]`` (rewrites the table in docs/tool-accuracy.md,
naming the code that measured it: a clean commit, :func:`selfcal.benchmarks.doc_blocks.code_version`).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, code_version, codes_note, print_table
from selfcal.benchmarks.tracker.sim import make_case
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.identify import IdentificationWarning
from selfcal.calibration.tracker.accuracy import tracker_accuracy
from selfcal.calibration.tracker.identify import identify_tracker
from selfcal.errors import UsageError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.tool_error import ToolErrorModel, workspace_sample
from selfcal.robot.definition import load_robot
from selfcal.sim.compliance import SHOULDER, JointMisfit
from selfcal.sim.gear import draw_gear
from selfcal.threads import limit_threads

__all__ = [
    "calibrate",
    "draw",
    "true_points",
    "misfit",
    "run",
    "table",
    "main",
    "mark",
    "coverage",
    "coverage_if_right",
    "right_range",
    "ROBOTS",
    "NOISE_MM",
    "MODELS",
    "RIGHT_DRAWS",
]

ROBOTS = ("er4u-paper", "ur5e", "kr6-r900")
NOISE_MM = (0.02, 0.1, 0.5)
MODELS = ("fits", "compliance", "gear")
ROWS = 30
SPAN = 0.7
COUNT = 128
RIGHT_DRAWS = 400
"""Errors drawn from a draw's own prediction by :func:`coverage_if_right`."""
REGIONS = ("inside", "edge", "workspace")
DOC = ROOT / "docs" / "tool-accuracy.md"
BLOCK = "benchmark_tool_accuracy"


def misfit(case, model: str, seed: int) -> JointMisfit | None:
    """The true robot's misfit of the joints under ``model`` (:data:`MODELS`) for the draw
    ``seed``: None (``fits``), :data:`selfcal.sim.compliance.SHOULDER` (``compliance``) or the
    truth's eccentric gear (``gear``, :func:`selfcal.sim.gear.draw_gear` on the true chain)."""
    if model not in MODELS:
        raise UsageError(f"unknown model {model!r}: one of {', '.join(MODELS)}")
    if model == "fits":
        return None
    return SHOULDER if model == "compliance" else draw_gear(case.true, case.robot.limits, seed)


def _bend(q: np.ndarray, bend: JointMisfit | None) -> np.ndarray:
    """The joints the true robot turns to for readings ``q`` under the misfit ``bend``."""
    return q if bend is None else bend.bent(q)


def calibrate(robot, sigma_m: float, model: str, seed: int):
    """One draw's simulated case (:func:`selfcal.benchmarks.tracker.sim.make_case`), its
    training joints ``q`` (ROWS, n), its calibration's predicted accuracy
    (:class:`selfcal.calibration.tracker.accuracy.TrackerAccuracy`) and the true robot's misfit
    (:func:`misfit`; the calibration never sees it)."""
    case = make_case(robot, seed=seed)
    bend = misfit(case, model, seed)
    rng = np.random.default_rng(seed + 500)
    lim = np.clip(robot.limits, -np.radians(170.0), np.radians(170.0))
    mid, half = lim.mean(axis=1), SPAN * (lim[:, 1] - lim[:, 0]) / 2
    q = rng.uniform(mid - half, mid + half, (ROWS, robot.n))
    xyz = fk_tool(case.true, _bend(q, bend))[:, :3, 3] + rng.normal(0.0, sigma_m, (ROWS, 3))
    meas = TrackerMeasurements(q, xyz, None, None, None, None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        res = identify_tracker(case.nominal, meas, sigma_t_m=sigma_m)
        acc = tracker_accuracy(case.nominal, meas, res, robot.limits, sigma_t_m=sigma_m,
                               sigma_r_rad=1e-4, count=COUNT)  # fmt: skip
    assert acc is not None
    return case, q, acc, bend


def true_points(case, bend: JointMisfit | None, q: np.ndarray) -> np.ndarray:
    """(m, 3) the true robot's tool points (mm) at the readings ``q`` (m, n), the links at
    ``bend``'s joints (:func:`misfit`)."""
    return fk_tool(case.true, _bend(q, bend))[:, :3, 3] * 1e3


def draw(robot, sigma_m: float, model: str, seed: int) -> dict[str, np.ndarray]:
    """One draw: per region, the predicted 95 % bound, the predicted RMS without and with the
    model error, and the true error (mm) at its joint vectors."""
    case, q, acc, bend = calibrate(robot, sigma_m, model, seed)
    sample = workspace_sample(q, robot.limits, count=COUNT, seed=seed + 1)
    out = {}
    for name in REGIONS:
        qq = getattr(sample, name)
        p = acc.error_model.predicted(qq)
        true = true_points(case, bend, qq)
        out[name] = np.stack([p["position_95_mm"], p["estimation_95_mm"], p["position_rms_mm"],
                              np.linalg.norm(p["position_mm"] - true, axis=1)])  # fmt: skip
    return out


def run(draws: int = 30, robots=ROBOTS, noise_mm=NOISE_MM, models=MODELS) -> list[dict]:
    """One row per (robot, noise, model, region): coverage, coverage of the covariance alone,
    pooled predicted / true RMS and the 10-90 % range of the per-draw ratios, and the code that
    measured it (``code``, :func:`selfcal.benchmarks.doc_blocks.code_version` at the start)."""
    code = code_version()
    rows = []
    for rname in robots:
        robot = load_robot(rname)
        for s_mm in noise_mm:
            for model in models:
                t0 = time.perf_counter()
                got = [draw(robot, s_mm / 1e3, model, seed) for seed in range(draws)]
                for region in REGIONS:
                    d = [g[region] for g in got]
                    rows.append({"robot": rname, "noise_mm": s_mm, "model": model,
                                 "region": region, "draws": draws, "code": code,
                                 "points": sum(x.shape[1] for x in d), **coverage(d)})  # fmt: skip
                print(f"{rname} {s_mm} mm {model}: {time.perf_counter() - t0:.1f} s",
                      file=sys.stderr)  # fmt: skip
    return rows


def coverage(d: list[np.ndarray]) -> dict[str, float]:
    """The position statistics of one row's draws ``d``, each (4+, m) per joint vector: the
    predicted 95 % bound, the same without the model error, the predicted RMS and the true
    error (mm). ``coverage`` and ``coverage_covariance`` (the share of points whose true error
    is within the bound), ``ratio`` (the pooled predicted / true RMS) with the 10-90 % range
    ``ratio_10`` / ``ratio_90`` of the per-draw ratios, and ``true_rms_mm``."""
    a = np.concatenate(d, axis=1)
    ratio = [np.sqrt(np.mean(x[2] ** 2) / np.mean(x[3] ** 2)) for x in d]
    return {
        "coverage": float(np.mean(a[3] <= a[0])),
        "coverage_covariance": float(np.mean(a[3] <= a[1])),
        "ratio": float(np.sqrt(np.mean(a[2] ** 2) / np.mean(a[3] ** 2))),
        "ratio_10": float(np.quantile(ratio, 0.1)),
        "ratio_90": float(np.quantile(ratio, 0.9)),
        "true_rms_mm": float(np.sqrt(np.mean(a[3] ** 2))),
    }


def coverage_if_right(em: ToolErrorModel, q: np.ndarray, seed: int,
                      count: int = RIGHT_DRAWS) -> np.ndarray:  # fmt: skip
    """(2, count) the coverage a right prediction would show at the joint vectors ``q`` (m, n):
    ``count`` errors of the whole chain drawn from the prediction ``em`` itself (the estimated
    parameters' error from their covariance, carried through the chain to every joint vector
    at once, so correlated as the calibration's one error is; the model error per coordinate
    with its growth, drawn independently at every joint vector, which the prediction does not
    correlate), each one's share of ``q`` within the predicted 95 % bound: position (row 0) and
    orientation (row 1; nan without one). Seeded by ``seed``.

    One calibration's errors at the joint vectors are one draw of the parameters' error: over a
    few calibrations the pooled coverage of even a right bound spreads widely
    (:func:`right_range`), the more so the fewer parameter directions move the tool."""
    rng = np.random.default_rng(seed)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w, V = np.linalg.eigh(em.covariance)
    delta = rng.standard_normal((count, w.size)) @ (V * np.sqrt(np.clip(w, 0.0, None))).T
    e = np.einsum("mip,kp->kmi", em.jacobian(q), delta)  # (count, m, 6)
    grow = np.sqrt(em.model_error_factor(q))[None, :, None]
    e[:, :, :3] += rng.standard_normal((count, len(q), 3)) * em.model_error_m * grow
    e[:, :, 3:] += rng.standard_normal((count, len(q), 3)) * (em.model_error_rad or 0.0) * grow
    p = em.predicted(q)
    pos = np.linalg.norm(e[:, :, :3], axis=2) * 1e3 <= p["position_95_mm"]
    rot = np.degrees(np.linalg.norm(e[:, :, 3:], axis=2)) <= p["orientation_95_deg"]
    has_rot = bool(np.all(np.isfinite(p["orientation_95_deg"])))
    return np.stack([pos.mean(axis=1), rot.mean(axis=1) if has_rot else np.full(count, np.nan)])


def right_range(per_draw: list[np.ndarray], level: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
    """The central ``level`` range (low (k,), high (k,)) of the coverage a right prediction would
    pool over a row's draws, ``per_draw`` each (k, count) from :func:`coverage_if_right` (the
    same ``count``): the j-th pooled value the mean of every draw's j-th."""
    pooled = np.mean(np.stack(per_draw), axis=0)  # (k, count)
    lo, hi = np.quantile(pooled, [(1 - level) / 2, (1 + level) / 2], axis=1)
    return lo, hi


def mark(v: float, lo: float, hi: float) -> str:
    """ " (outside)" when ``v`` is outside the target ``lo``-``hi`` (a table cell's suffix)."""
    return "" if lo <= v <= hi else " (outside)"


def table(rows: list[dict]) -> str:
    """The Markdown table of :func:`run`'s rows."""
    head = (
        "| robot | noise (mm) | model | region | true RMS (mm) | coverage of the 95 % bound "
        "(target 90-98 %) | covariance alone | predicted / true RMS (target 0.7-1.4) | per draw "
        "10-90 % |\n|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['robot']} | {r['noise_mm']:g} | {r['model']} | {r['region']} | "
        f"{r['true_rms_mm']:.3f} | {100 * r['coverage']:.1f} %"
        f"{mark(r['coverage'], 0.9, 0.98)} | {100 * r['coverage_covariance']:.1f} % | "
        f"{r['ratio']:.2f}{mark(r['ratio'], 0.7, 1.4)} | {r['ratio_10']:.2f}-{r['ratio_90']:.2f} |"
        for r in rows
    ]
    d = rows[0]
    note = (
        f"\n{d['draws']} draws per row, {ROWS} training positions in the central "
        f"{SPAN:.0%} of each joint's range, {COUNT} joint vectors per region and draw; "
        "`uv run python -m selfcal.benchmarks.tracker.accuracy --write-docs` (options "
        f"`--robots`, `--models`, `--noise-mm`){codes_note(rows, ('robot', 'model'))}."
    )
    return head + "\n".join(lines) + "\n" + note


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread) and print, or write, the table."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=30, help="draws per row (default 30)")
    ap.add_argument("--robots", type=_names(ROBOTS), default=ROBOTS,
                    help=f"robots, comma-separated (default {','.join(ROBOTS)})")  # fmt: skip
    ap.add_argument("--models", type=_names(MODELS), default=MODELS,
                    help=f"models, comma-separated (default {','.join(MODELS)})")  # fmt: skip
    ap.add_argument("--noise-mm", type=lambda t: tuple(float(x) for x in t.split(",")),
                    default=NOISE_MM, help="tracker noise levels (mm per coordinate), "
                    f"comma-separated (default {','.join(f'{x:g}' for x in NOISE_MM)})")  # fmt: skip
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the table in docs/tool-accuracy.md")  # fmt: skip
    args = ap.parse_args(argv)
    rows = run(args.draws, args.robots, args.noise_mm, args.models)
    return print_table(table(rows), DOC, BLOCK, write=args.write_docs)


def _names(known: tuple[str, ...]):
    """An argparse type: a comma-separated list of ``known`` names (an unknown one refused,
    naming the choices)."""

    def parse(text: str) -> tuple[str, ...]:
        got = tuple(x.strip() for x in text.split(",") if x.strip())
        bad = [x for x in got if x not in known]
        if bad or not got:
            raise argparse.ArgumentTypeError(f"{', '.join(bad) or text!r}: one of "
                                             f"{', '.join(known)}")  # fmt: skip
        return got

    return parse


if __name__ == "__main__":
    sys.exit(main())
