"""Benchmark: can the drift check find the real tier's lens change at all? (issue #29)

The real tier writes a small lens change into a real calibration's file (k3, held at 0 by the
calibration, moved by ``--k3``) and expects ``selfcal check`` of the held-out group (real images
of the unchanged arm) to say "changed" (docs/real-data.md). This prints what that rests on, in
the check's own metric (:mod:`selfcal.calibration.drift.images`, whitened by its ``Sigma``):
the move of the prediction (px RMS) beside the held-out residuals' RMS before and after; the
camera's directed test (its 8 free parameters' columns) on the unchanged residuals, on the
moved ones, and the move's own noncentrality ``lambda`` in it with the cross term between the
two (``T_moved = T_unchanged + 2 cross + lambda``); the power that ``lambda`` gives the camera
test at its Bonferroni level and a test knowing the move's direction at alpha; and the k3 move
that the camera test would find with 95 % power. ``--sandwich``: the same with the calibration's
own frames' sandwich covariance added to the estimate covariance the check reads
(:func:`selfcal.benchmarks.drift.folds.folds_of`; the calibration runs again: minutes).

Run: ``uv run python -m selfcal.benchmarks.drift.real_lens CAL HELD [--k3 0.1] [--sandwich]``
(the real tier's folders, docs/real-data.md).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2, ncx2

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.view_jitter import psd_part
from selfcal.calibration.drift.covariance import view_covariance
from selfcal.calibration.drift.images import (
    ALPHA,
    calibration_error_model,
    calibration_views,
    estimate_covariance,
)
from selfcal.calibration.drift.p_value import known_change_power
from selfcal.io.atomic import write_text_atomic
from selfcal.io.board_calibration import read_board_calibration
from selfcal.threads import limit_threads

__all__ = ["main"]

TESTS = 12
"""The check's tests on an eye-in-hand six-joint arm (the omnibus, the camera, the two mounts'
translation and rotation, six joints): Bonferroni's factor."""


def main(argv: list[str] | None = None) -> int:
    """Print the lens change's parts (module docstring)."""
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("calibration", type=Path, help="the folder of selfcal calibrate")
    ap.add_argument("held", type=Path, help="a folder of selfcal import: the held-out images")
    ap.add_argument("--k3", type=float, default=0.1, help="the lens change (default 0.1)")
    ap.add_argument("--sandwich", action="store_true", help="also with the sandwich (minutes)")
    a = ap.parse_args(argv)
    limit_threads(1)
    path = a.calibration / "calibration.json"
    cal = read_board_calibration(path)
    doc = json.loads(path.read_text())
    doc["cameras"][0]["parameters"]["k3"] = doc["cameras"][0]["parameters"].get("k3", 0.0) + a.k3
    with tempfile.TemporaryDirectory() as d:
        moved = read_board_calibration(
            write_text_atomic(Path(d) / "calibration.json", json.dumps(doc))
        )
    em = calibration_error_model(cal, str(path))
    h = held_out_views(cal, a.held, cameras=(cal.camera_names[0],))
    new = [(f, X, uv) for _, f, _, _, X, uv in h.views]
    v0, vk = (calibration_views(c, em, h.q, new, where=str(path)) for c in (cal, moved))
    r0, rk = (np.concatenate([v.r for v in vs]) for vs in (v0, vk))
    k = len(r0) // 2
    print(f"{path}, k3 {a.k3:+g}, {len(v0)} held-out views: the prediction moves "
          f"{np.sqrt((rk - r0) @ (rk - r0) / k):.4f} px RMS; the residuals' RMS "
          f"{np.sqrt(r0 @ r0 / k):.4f} -> {np.sqrt(rk @ rk / k):.4f} px")  # fmt: skip
    C = estimate_covariance(cal, em)
    metrics = [("the check's covariance", C)]
    if a.sandwich:
        from selfcal.benchmarks.drift.folds import folds_of

        metrics.append(("with its own frames' sandwich", psd_part(C + folds_of(a.calibration)[2])))
    for label, CC in metrics:
        L = np.linalg.cholesky(view_covariance(CC, v0))
        G = np.linalg.solve(L, np.concatenate([v.cam for v in v0]))
        P = G @ np.linalg.pinv(G)
        w0, wm = np.linalg.solve(L, r0), np.linalg.solve(L, rk - r0)
        dof = int(np.linalg.matrix_rank(G))
        t0, cross, lam = float(w0 @ P @ w0), float(w0 @ P @ wm), float(wm @ P @ wm)
        level = chi2.isf(ALPHA / TESTS, dof)
        needed = brentq(lambda x, lv=level, n=dof: ncx2.sf(lv, n, x) - 0.95, 1e-3, 1e4)
        print(f"  {label}: the camera test ({dof} dof) {t0:.2f} unchanged (p {chi2.sf(t0, dof):.2g}), "
              f"{t0 + 2 * cross + lam:.2f} moved (p {chi2.sf(t0 + 2 * cross + lam, dof):.2g}) = "
              f"{t0:.2f} + 2 x {cross:.2f} + lambda {lam:.2f}; lambda's power at "
              f"{ALPHA:g}/{TESTS}: {ncx2.sf(level, dof, lam):.3f}; a test knowing the move's "
              f"direction (noncentrality {float(wm @ wm):.2f}) at {ALPHA:g}: "
              f"{known_change_power(float(wm @ wm), ALPHA):.3f}; 95 % power at k3 "
              f"{a.k3 * np.sqrt(needed / lam):+.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
