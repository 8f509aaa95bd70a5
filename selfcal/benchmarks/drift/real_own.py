"""Benchmark: why ``selfcal check CAL CAL`` (a calibration's own images) said "changed" (#29).

The check's tests on the calibration's own frames, all of them taken as new (as the check did
before it left them out, :mod:`selfcal.calibration.drift.own`), in three metrics: the check's
own covariance (``Sigma``, :mod:`selfcal.calibration.drift.images`), ``Sigma`` without the
estimate's part ``H C H^T``, and white noise (``s^2 I + H C H^T``, ``s`` the file's white
corner noise or the bounds'). Per metric: the chi-square of all the residuals and each directed
test (how much a candidate change's fit lowers it, its rank, its p-value). Before them, what the
fit left: how much an equal-weight least-squares fit of each candidate lowers the residuals'
squared norm, as a share of it (zero to rounding where the calibration estimated that change
with equal weights and the chain's poses, as the board route does).

Run: ``uv run python -m selfcal.benchmarks.drift.real_own CAL`` (CAL the folder of ``selfcal
calibrate``, which holds its dataset), e.g. on the real tier's sets after ``uv run pytest -m
real`` has imported and calibrated them (docs/real-data.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.linalg import solve_triangular
from scipy.stats import chi2

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.drift.attribution import candidate_fits
from selfcal.calibration.drift.covariance import view_covariance
from selfcal.calibration.drift.images import (
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    view_noise,
)
from selfcal.calibration.drift.views import ViewJacobians
from selfcal.io.board_calibration import read_board_calibration
from selfcal.threads import limit_threads

__all__ = ["main"]


def _tests(sigma: np.ndarray, r: np.ndarray, views: list[ViewJacobians], e2h: bool) -> str:
    """The check's tests of the residuals ``r`` under the covariance ``sigma``, in words."""
    L = np.linalg.cholesky(sigma)

    def white(M: np.ndarray) -> np.ndarray:
        return solve_triangular(L, M, lower=True)

    rw = white(r)
    T = float(rw @ rw)
    fits = candidate_fits(white, rw, views, eye_to_hand=e2h)
    parts = [f"chi-square {T:.1f} on {len(r)} (p = {chi2.sf(T, len(r)):.2g})"]
    for key, (drop, rank) in fits.directed.items():
        parts.append(f"{key} {max(drop, 0.0):.1f} on {rank} (p = {chi2.sf(drop, rank):.2g})")
    return "; ".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("calibration", type=Path, help="the folder of selfcal calibrate")
    root: Path = ap.parse_args(argv).calibration
    limit_threads(1)
    cal = read_board_calibration(path := root / "calibration.json")
    held = held_out_views(cal, root, cameras=(cal.camera_names[0],))  # its own frames
    em = calibration_error_model(cal, str(path))
    views = calibration_views(cal, em, held.q, [(f, X, uv) for _, f, _, _, X, uv in held.views],
                              where=str(path))  # fmt: skip
    r = np.concatenate([v.r for v in views])
    C = estimate_covariance(cal, em)
    H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in views])
    e2h = cal.eye_to_hand
    print(f"{path}: {len(views)} own frame(s), {len(r) // 2} corners, "
          f"{np.sqrt(r @ r / (len(r) // 2)):.3f} px RMS")  # fmt: skip
    left = []
    for key, G in (("camera", np.concatenate([v.cam for v in views])),
                   ("tool mount", np.concatenate([v.tool for v in views])),
                   ("world", np.concatenate([v.world for v in views])),
                   ("joint offsets", np.concatenate([v.joints for v in views]))):  # fmt: skip
        fit = G @ np.linalg.lstsq(G, r, rcond=None)[0]
        left.append(f"{key} {float(fit @ fit) / float(r @ r):.1e}")
    print("equal-weight fit of each change, share of the squared residuals: " + "; ".join(left))
    sigma = view_covariance(C, views)
    print("the check's covariance: " + _tests(sigma, r, views, e2h))
    print("without H C H^T: " + _tests(sigma - H @ C @ H.T, r, views, e2h))
    s = view_noise(cal, str(path)).pixel_sigma_px
    white_sigma = s**2 * np.eye(len(r)) + H @ C @ H.T
    print(f"white noise ({s:.3f} px) + H C H^T: " + _tests(white_sigma, r, views, e2h))
    return 0


if __name__ == "__main__":
    sys.exit(main())
