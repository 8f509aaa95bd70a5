"""Benchmark: how often the folds' whitened excess (the drift check's second null, issue #29) is
counted on simulated board calibrations, by the rule with the held-out rows' covariance between
them and by session 23's rule that took them as independent.

Per draw: the analytic scenario of ``--setup`` (eye-in-hand ``scenarios/mono-charuco.toml`` on
``--robot``, eye-to-hand ``scenarios/eye-to-hand.toml`` on its UR5e) acquired and calibrated as
``selfcal run`` does (the deviation prior the simulated arm's own spread,
:func:`selfcal.benchmarks.board.accuracy_draw.prior`), then its folds' held-out frames
(:func:`selfcal.calibration.board.accuracy.held_out_errors`, :func:`selfcal.calibration.whitened.whitened_rows`) read as the
accuracy block reads them. For the position and the orientation: the whitened sum ``Q = sum_i
e_i^T V_i^-1 e_i`` against ``d rows``; the estimation's share of the rows' covariance (``mean
tr(V_i^-1 S_i) / d``); ``Q``'s null variance with the covariance between rows over ``2 d rows``
(:func:`selfcal.calibration.whitened.whitened_null`); whether an excess is counted by the rule
(:func:`selfcal.calibration.whitened.whitened_threshold`, the calibration's own figure
``whitened_excess_mm`` / ``_deg`` beside it) and by session 23's (``(Q - d rows) / sqrt(2 d
rows) > 2``, the rows independent). The simulated arms fit their model, but the calibration
holds some of their perturbed parameters at the drawing: an excess the folds show is that
deviation (which the check carries otherwise) or chance.

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.drift.whitened_level --draws 10 --setup
eye-to-hand [--robot ur5e er4u-paper] [--noise-px 0.2] [--jobs 1]``; ``--calibration CAL
[CAL ...]``: the same of folders ``selfcal calibrate`` wrote (calibrated again with the default
deviation), e.g. the real tier's (docs/real-data.md).
"""

from __future__ import annotations

import json
import sys
import tempfile
import warnings
from contextlib import redirect_stderr, redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import SCENARIO, prior
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.accuracy import (
    ORIENTATION,
    POSITION,
    held_out_errors,
)
from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.fold_fits import fold_bounds
from selfcal.calibration.whitened import whitened_null, whitened_rows, whitened_threshold
from selfcal.config.scenario import load_scenario, scenarios_dir
from selfcal.pipeline.run import run_acquire
from selfcal.threads import limit_threads

__all__ = ["draw", "main"]

SCENARIOS = {"eye-in-hand": SCENARIO, "eye-to-hand": scenarios_dir() / "eye-to-hand.toml"}
POSES = 30


def _rows(root: Path, sigma_px: float, deviation: Deviation | None) -> tuple[dict, tuple | None]:
    """The calibration of the dataset ``root`` and its folds' whitened rows (``e``, ``V``,
    ``between``; None without folds)."""
    det = calibrate_board_dataset_detailed(root, deviation=deviation)
    cal, obs = det.result, det.observations
    me = ((cal.accuracy or {}).get("model_error")) or {}
    if obs is None or det.fit.selection is None or det.fit.nominal is None or not me:
        return me, None
    T_tp = np.asarray((cal.accuracy or {})["T_tool_point_si"], dtype=float)
    h = [held_out_errors(obs, fit, out, T_tp, cr)
         for out, fit, cr in fold_bounds(obs, det.fit.selection,
                                         det.fit.nominal.model.joint_offsets, T_tp, sigma_px)]  # fmt: skip
    return me, whitened_rows(h)


def _statistics(rows: tuple, me: dict) -> dict:
    """Per coordinate set of the whitened ``rows`` (``e``, ``V``, ``between``): the whitened sum,
    its degrees of freedom, its threshold, the estimation's share, the null variance's ratio,
    both rules' verdicts and the calibration's own figure (``me``: its block's
    ``model_error``)."""
    e, V, between = rows
    out: dict = {}
    for name, b, key in (("position", POSITION, "whitened_excess_mm"),
                         ("orientation", ORIENTATION, "whitened_excess_deg")):  # fmt: skip
        x, Vb, Bb = e[:, b], V[:, b, b], between[:, b, :, b]
        k = np.arange(len(x))
        S = Bb[k, :, k, :]  # the diagonal blocks: each row's own estimation error S_i
        Q = float(np.sum(x * np.linalg.solve(Vb, x[..., None])[..., 0]))
        dof, var, _ = whitened_null(Vb, Bb)
        threshold = whitened_threshold(Vb, Bb)
        out[name] = {
            "Q": Q,
            "dof": dof,
            "threshold": threshold,
            "var_ratio": var / (2.0 * dof),
            "share": float(np.mean(np.trace(np.linalg.solve(Vb, S), axis1=1, axis2=2)) / 3.0),
            "old": bool((Q - dof) / np.sqrt(2.0 * dof) > Z_MODEL_ERROR),
            "new": bool(Q > threshold),
            "figure": bool((me.get(key) or 0.0) > 0.0),
        }
    return out


def draw(args: tuple) -> dict:
    """One draw (``setup``, ``robot`` or None, ``sigma_px``, ``seed``; module docstring): per
    coordinate set the whitened sum, its degrees of freedom, the estimation's share, the null
    variance's ratio and both rules' verdicts, and the calibration's own figure."""
    setup, robot, sigma_px, seed = args
    over: dict = {"noise": {"render": False, "pixel_sigma": sigma_px, "seed": seed},
                  "trajectory": {"poses": POSES, "seed": seed}, "perturbation": {"seed": seed}}  # fmt: skip
    if robot is not None:
        over["robot"] = {"model": robot}
    try:
        with (tempfile.TemporaryDirectory(prefix="selfcal-wl-") as d, warnings.catch_warnings(),
              redirect_stdout(StringIO()), redirect_stderr(StringIO())):  # fmt: skip
            warnings.simplefilter("ignore")
            s = load_scenario(SCENARIOS[setup], over)
            root = run_acquire(s, Path(d) / "run", quiet=True)
            me, rows = _rows(root, sigma_px, prior(s))
    except Exception as exc:  # a draw that fails is counted, not fatal
        return {"status": f"failed: {type(exc).__name__}: {exc}"}
    if rows is None:
        return {"status": "no folds"}
    return {"status": "ok", "rows": len(rows[0])} | _statistics(rows, me)


def _summary(got: list[dict]) -> str:
    """One coordinate set's line over the draws ``got`` (:func:`draw`'s entries)."""
    n, r = len(got), np.array([g["Q"] / g["dof"] for g in got])
    count = {k: sum(g[k] for g in got) for k in ("new", "figure", "old")}
    spread = float(np.var(r) * np.mean([g["dof"] for g in got]) / 2.0)
    return (f"counted by the rule {count['new']} of {n} (the calibration's figure "
            f"{count['figure']}), by session 23's {count['old']}; Q / dof median "
            f"{np.median(r):.2f}, mean {np.mean(r):.2f}, variance over the draws x dof / 2 "
            f"{spread:.2f}; null variance / (2 dof) mean "
            f"{np.mean([g['var_ratio'] for g in got]):.2f}, median "
            f"{np.median([g['var_ratio'] for g in got]):.2f}; estimation share mean "
            f"{np.mean([g['share'] for g in got]):.3f}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the draws and print per setup the rules' counts (module docstring)."""
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=10, help="per setup, robot and noise level")
    ap.add_argument("--setup", nargs="+", choices=sorted(SCENARIOS), default=["eye-to-hand"])
    ap.add_argument("--robot", nargs="+", default=[None],
                    help="the eye-in-hand robots (default the scenario's ER-4u)")  # fmt: skip
    ap.add_argument("--noise-px", type=float, nargs="+", default=[0.2])
    ap.add_argument("--seed", type=int, default=0, help="the first draw's seed")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--calibration", nargs="+", type=Path, default=[],
                    help="instead: these folders of selfcal calibrate (a board dataset "
                    "calibrated; run again), their folds' rows")  # fmt: skip
    a = ap.parse_args(argv)
    limit_threads()
    for root in a.calibration:
        sigma = float(
            json.loads((root / "calibration.json").read_text())["bounds"]["pixel_sigma_px"]
        )
        me, rows = _rows(root, sigma, None)
        if rows is None:
            print(f"{root}: no folds")
            continue
        for name, g in _statistics(rows, me).items():
            print(f"{root} {name}: {len(rows[0])} rows, whitened sum / dof {g['Q'] / g['dof']:.2f} "
                  f"against the threshold's {g['threshold'] / g['dof']:.2f} (independent rows: "
                  f"{whitened_threshold(rows[1][:, :3, :3]) / g['dof']:.2f}), null variance / "
                  f"(2 dof) {g['var_ratio']:.2f}, estimation share {g['share']:.3f}; counted by "
                  f"the rule {g['new']}, session 23's {g['old']}")  # fmt: skip
    if a.calibration:
        return 0
    for setup in a.setup:
        for robot in a.robot if setup == "eye-in-hand" else [None]:
            for sigma in a.noise_px:
                items = [(setup, robot, sigma, a.seed + k) for k in range(a.draws)]
                res = map_jobs(draw, items, a.jobs)
                ok = [r for r in res if r["status"] == "ok"]
                label = f"{setup}, {robot or 'scenario robot'}, {sigma} px"
                print(f"{label}: {len(ok)} of {len(res)} draws with folds")
                for r in res:
                    if r["status"] != "ok":
                        print(f"  {r['status']}")
                for name in ("position", "orientation"):
                    if ok:
                        print(f"  {name}: {_summary([r[name] for r in ok])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
