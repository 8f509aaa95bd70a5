"""Benchmark: the calibration noise a new view's own is held to in ``selfcal check`` (issue #29,
the ER-4u's unchanged checks said "cannot tell" in 3 % where the level is set for 1 %).

A new view is called noisier than the calibration (its check then says "cannot tell" at best)
where its white corner noise, outside its pose span and the camera's directions
(:func:`selfcal.calibration.drift.views.view_white_px`), is above the calibration's at
``WHITE_LEVEL / n`` a view. Per simulated calibration (the drift benchmark's, seeded alike:
:func:`selfcal.benchmarks.board.accuracy_draw.simulated_calibration`) this prints, against the
simulated corner noise ``s``, the square of each noise the view could be held to: the bounds'
(``bounds.pixel_sigma_px``, the final fit's RMS corrected for its parameters alone: the check's
until session 27) and the frames' white noise (``accuracy.view_jitter.white_px``, the same
statistic as the view's over the same pixels: the check's since), and the effective unknowns of
the frames' joint read-back corrections the fit estimated (each ``1 - posterior / prior
variance``: the pixels' share of it, which the bounds' correction leaves out). Beside them, the
share of five-view checks of the unchanged arm such a calibration would call noisy, each view
with the corner count of the calibration's frames on average (``bounds.observations /
frames_used``; ``2 k - 14`` degrees of freedom, 6 pose and 8 camera columns): ``1 - (1 -
P(chi2_d > isf(level, d) h^2 / s^2))^5`` with ``h`` each reference (the level's 0.998 % at
``h = s``), and in how many calibrations the check runs the folds' second null
(:func:`selfcal.calibration.drift.fold_error.fold_error_model`, the other way to "cannot tell").

Run: ``MUJOCO_GL=egl nice -n 10 uv run python -m selfcal.benchmarks.drift.noise_reference
--calibrations 10 [--noise-px 0.05 0.2] [--robot er4u-paper ur5e kr6-r900] [--jobs 1]``.
"""

from __future__ import annotations

import sys

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import simulated_calibration
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board import bounds as board_bounds_module
from selfcal.calibration.board.view_jitter import view_jitter_from_json
from selfcal.calibration.drift.fold_error import fold_error_model
from selfcal.calibration.drift.images import calibration_error_model
from selfcal.calibration.drift.p_value import chi2_isf, chi2_sf
from selfcal.calibration.drift.views import view_noise, white_level
from selfcal.solver.covariance import inverse_columns
from selfcal.threads import limit_threads

__all__ = ["calibration_noise", "main", "noisy_share"]

VIEWS = 5
"""New views per check (the drift benchmark's)."""
COLUMNS = 14
"""A view's pose (6) and camera (8: the scenario's free parameters) columns."""


def noisy_share(reference_px: float, sigma_px: float, dof: int, views: int = VIEWS) -> float:
    """The share of checks of ``views`` new views, each with white corner noise ``sigma_px``
    over ``dof`` degrees of freedom outside its spans, that call one noisier than the
    calibration's ``reference_px`` (px) at :func:`white_level` a view."""
    level = white_level(views)
    p = float(chi2_sf(chi2_isf(level, dof) * (reference_px / sigma_px) ** 2, dof))
    return 1.0 - (1.0 - p) ** views


def calibration_noise(args: tuple[float, int, str | None]) -> dict:
    """One simulated calibration (corner noise ``sigma_px``, ``seed``, ``robot`` or None: the
    scenario's): its noise references against ``sigma_px`` (module docstring), the joint
    corrections' effective unknowns (0 where its joints are read exactly) and the shares of
    five-view checks called noisy against each."""
    sigma_px, seed, robot = args
    captured: list = []
    make = board_bounds_module.board_problem

    def keep(*a, **k):  # the bounds' problem: its Jacobian at the estimate, the prior's weights
        prob = make(*a, **k)
        captured.append((prob, k))
        return prob

    board_bounds_module.board_problem = keep
    try:
        cal, _ = simulated_calibration(sigma_px, seed, robot=robot)
    finally:
        board_bounds_module.board_problem = make
    assert cal.bounds is not None
    found = view_jitter_from_json(cal.accuracy, "calibration.json")
    white = np.nan if found is None or found.white_px is None else float(found.white_px)
    prob, kw = captured[0]  # board_bounds' own (the accuracy block's folds come after it)
    absorbed = 0.0
    if kw["joint_sigma"] is not None:
        P, frames = prob.problem, int(kw["n_frames"])
        js = np.broadcast_to(np.asarray(kw["joint_sigma"], float), (cal.model.n,))
        dq = P.columns("poses")[-frames * len(js) :]
        weight = np.tile(kw["pixel_sigma_px"] / js, frames)
        posterior = np.diag(inverse_columns(P.jacobian(P.x0), dq)[dq])
        absorbed = float(np.sum(1.0 - weight**2 * posterior))
    em = calibration_error_model(cal, "calibration.json")
    folds = fold_error_model(em, cal.accuracy, view_noise(cal).misfit_counted) is not None
    k = cal.bounds.observations / max(cal.frames_used, 1)
    dof = int(round(2 * k)) - COLUMNS
    bounds = float(cal.bounds.pixel_sigma_px)
    return {"bounds2": (bounds / sigma_px) ** 2, "white2": (white / sigma_px) ** 2,
            "absorbed": absorbed, "dof": dof, "folds": int(folds),
            "share_bounds": noisy_share(bounds, sigma_px, dof),
            "share_white": noisy_share(white, sigma_px, dof),
            "share_true": noisy_share(sigma_px, sigma_px, dof)}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the calibrations (one BLAS thread per process) and print one line per robot and
    noise level."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--calibrations", type=int, default=10, help="per row (default 10)")
    ap.add_argument("--noise-px", type=float, nargs="+", default=[0.05, 0.2],
                    help="corner noise levels (default 0.05 0.2)")  # fmt: skip
    ap.add_argument("--robot", nargs="+", default=[None], metavar="ROBOT",
                    help="robot files (default the scenario's ER-4u)")  # fmt: skip
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    a = ap.parse_args(argv)
    print("| robot | noise (px) | calibrations | bounds' noise^2 / s^2 | frames' white noise^2 "
          "/ s^2 | joint corrections' unknowns | view dof | five-view checks called noisy: "
          "against the bounds' / the frames' white / s | folds' error counted |\n"
          "|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    for robot in a.robot:
        for s in a.noise_px:
            got = map_jobs(calibration_noise, [(s, seed, robot) for seed in
                                               range(1, a.calibrations + 1)], a.jobs)  # fmt: skip
            m = {key: float(np.mean([g[key] for g in got])) for key in got[0]}
            se = {key: float(np.std([g[key] for g in got], ddof=1) / np.sqrt(len(got)))
                  for key in ("bounds2", "white2")}  # fmt: skip
            print(f"| {robot or 'er4u-paper'} | {s:g} | {len(got)} | {m['bounds2']:.4f} "
                  f"(+- {se['bounds2']:.4f}) | {m['white2']:.4f} (+- {se['white2']:.4f}) | "
                  f"{m['absorbed']:.1f} | {m['dof']:.0f} | {100 * m['share_bounds']:.2f} % / "
                  f"{100 * m['share_white']:.2f} % / {100 * m['share_true']:.2f} % | "
                  f"{sum(g['folds'] for g in got)} |",
                  flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
