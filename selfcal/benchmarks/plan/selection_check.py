"""The plan's forecast of the selection against the calibration's own selection on one draw
(issue #30, docs/plan.md "The ER-4u's exchanged plan at the 90th percentile").

One draw of the plan-robots benchmark (:mod:`selfcal.benchmarks.plan.robots`: its plan of 12,
dithered, the arm drawn with the seed) is acquired as its draws are and calibrated by the board
route (``selfcal calibrate``'s); each nested candidate's fold RMS (px) of the calibration's
cross-validation is set beside

- ``expected``: the forecast's (:func:`selfcal.calibration.board.plan.selection.forecast_selection`,
  the deviation's expectation over arms), and as it was before session 18 (the left-out folds'
  joints corrected, as the training fits have them);
- ``linear``: the forecast's first-order formula with this draw's true deviation of the chain
  from its drawing (read from the draw's truth: a benchmark's check of the model, never a
  plan's input), noise-free but for the corners' ``2 sigma^2`` and the left-out frames'
  read-back errors: each fold's fit on the other folds' frames predicting the fold from its
  joints alone (:func:`linear_fold_rms`), the same with the fold's joints corrected (as the
  forecast had it before: the training fits' information), and the fit on every frame in
  sample beside the calibration's fit RMS (the forecast's candidate sets: the calibration's
  pool, ordered at its fair nominal, may order near-ties differently).

``--exact-joints`` records the joints without read-back quantisation, ``--analytic`` projects
the corners instead of rendering. Units: px, SI inside.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from selfcal.benchmarks.plan.robots import ROBOTS, cell, cell_target
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.atomic import write_text_atomic

__all__ = ["linear_fold_rms", "main"]


def linear_fold_rms(
    F_frames: np.ndarray,
    A_frames: np.ndarray,
    n_features: np.ndarray,
    out: np.ndarray,
    n_cam: int,
    M: np.ndarray,
    d: np.ndarray,
    sigma_px: float,
) -> float:
    """The RMS per feature (px, both coordinates) of the first-order fit of the camera's free
    parameters and the kinematic directions ``M`` (k, e) on the frames outside ``out`` (m,) bool
    predicting those in it, for the deviation ``d`` (k,) of the minimal parameters from the
    drawing (m, rad), the corners' noise ``sigma_px`` and the joints' read-back in expectation:
    ``sqrt(sigma^2 (2 n + e^T A_out e + trace(A_out's joints)) / n)``, ``e = -R d``
    (:func:`selfcal.calibration.board.plan.predict.linear_estimator` on the training frames'
    ``F_frames`` (m, p, p)), ``A_frames`` (m, p + j, p + j) how a frame is predicted
    (:func:`selfcal.calibration.board.plan.information.prediction_information`; ``F_frames``:
    as the forecast had it before, the predicted frames' joints corrected), ``n_features`` (m,)
    the features each shows. With ``out`` every frame: the fit on every frame in sample.
    Infinite when the fit's information is singular."""
    from selfcal.calibration.board.plan.predict import linear_estimator

    out = np.asarray(out, dtype=bool)
    train = ~out if (~out).any() else out
    fit = linear_estimator(F_frames[train].sum(axis=0), n_cam, M)
    if fit is None:
        return float("inf")
    p = len(fit[1])
    e = -fit[1] @ np.concatenate([np.zeros(n_cam), np.asarray(d, dtype=float)])
    A = A_frames[out].sum(axis=0)
    n = float(np.sum(n_features[out]))
    return float(sigma_px * np.sqrt(2.0 + (e @ A[:p, :p] @ e + np.trace(A[p:, p:])) / n))


def _acquire_draw(robot: str, root: Path, seed: int, sigma: float, render: bool, exact: bool):
    """The benchmark's plan of 12 for ``robot`` (its joints, rad) with draw ``seed`` acquired in
    ``root/seedN`` as :func:`selfcal.benchmarks.plan.robots._draw` acquires it."""
    from selfcal.benchmarks.plan.compare import sets_of
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.plan_files import joints_csv
    from selfcal.studies.montecarlo.run import acquire_draw

    setup, bp, _ = cell(robot)
    q, _ = sets_of(setup, 12, (12,), pixel_sigma_px=sigma)["sets"]["plan 12"]
    root.mkdir(parents=True, exist_ok=True)
    write_text_atomic(root / "joints.csv", joints_csv(q, setup.robot.edge_unit))
    write_text_atomic(root / "scenario.toml", scenario_text(robot, setup.camera, bp, len(q)))
    shutil.copyfile(cell_target(robot), root / "target.toml")
    deg = (q / setup.robot.edge_unit).tolist()
    shutil.rmtree(root / f"seed{seed}", ignore_errors=True)  # this script's own draw, acquired anew
    acquire_draw({"config": str(root / "scenario.toml"), "poses": len(deg), "pixel_sigma": sigma,
              "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
              "joints_deg": deg, "render": render, "quantize": not exact},
             root / f"seed{seed}")  # fmt: skip
    return setup, root / f"seed{seed}"


def main(argv: list[str] | None = None) -> int:
    """Acquire, calibrate and print the candidates' fold RMS (module docstring)."""
    from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
    from selfcal.calibration.board.plan.information import (
        board_model,
        frame_information,
        prediction_information,
    )
    from selfcal.calibration.board.plan.predict import Directions
    from selfcal.calibration.board.plan.selection import forecast_selection, selection_folds
    from selfcal.estimation.joint_report import encoder_sigma
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.alignment import express_in_frame, minimal_difference
    from selfcal.transforms import inv_pose

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="er4u-paper", choices=ROBOTS)
    ap.add_argument("--seed", type=int, default=30, help="the draw's seed (the benchmark's)")
    ap.add_argument("--pixel-sigma", type=float, default=0.04, help="the plan's corner noise, px")
    ap.add_argument("--analytic", action="store_true", help="corners projected, not rendered")
    ap.add_argument("--exact-joints", action="store_true", help="no read-back quantisation")
    ap.add_argument("--out", default="runs/selection-check")
    a = ap.parse_args(argv)
    sigma = a.pixel_sigma
    setup, root = _acquire_draw(a.robot, Path(a.out), a.seed, sigma, not a.analytic,
                                a.exact_joints)  # fmt: skip
    sel = calibrate_board_dataset_detailed(root).fit.selection
    assert sel is not None
    model = board_model(setup)
    q = np.radians(Dataset.open(root).joints_deg)
    truth = read_truth(root / "truth.json")
    assert truth.T_world_board is not None  # a board scenario's truth
    true_b = express_in_frame(truth.true_model, inv_pose(truth.T_world_board), like=model)
    d = minimal_difference(true_b, model)
    js = encoder_sigma(setup.robot)
    F = frame_information(setup, q, sigma, js)
    n = np.full(len(q), len(setup.board.layout()[0]), dtype=float)
    n_cam = setup.camera.n_free
    dirs = Directions(model)
    folds = selection_folds(model, q, dirs)
    A = prediction_information(setup, q, sigma, js)  # the left-out folds from their joints alone
    fc = forecast_selection(model, q, F, n, n_cam, setup_variance(setup), sigma, dirs, held_out=A)
    before = forecast_selection(model, q, F, n, n_cam, setup_variance(setup), sigma, dirs)
    every = np.ones(len(q), bool)
    print(f"{a.robot} seed {a.seed} ({'analytic' if a.analytic else 'rendered'}, "
          f"{'exact' if a.exact_joints else 'quantised'} joints): the calibration kept "
          f"{sel.candidates[sel.chosen].label}; the forecast {fc.label}")  # fmt: skip
    print(
        "| candidate | fold RMS: calibration (CV) | expected (forecast) (CV) | linear, true "
        "deviation | the same, the folds' joints corrected | fit RMS: calibration | linear, "
        "true deviation | expected, the folds' joints corrected (before session 18) (CV) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for c, cand in enumerate(sel.candidates):
        lin = [[linear_fold_rms(F, B, n, folds.out(f), n_cam, folds.directions[f][c], d, sigma)
                for f in range(len(folds.labels))] for B in (A, F)]  # fmt: skip
        M = dirs.of(cand.free_idx, cand.offset_joints)
        fit = "-" if cand.fit is None else f"{cand.fit.rms_px:.3f}"
        print(
            f"| {cand.label} | {_px(cand.fold_rms_px)} ({cand.cv_px:.3f}) | "
            f"{_px(fc.fold_rms_px[c])} ({fc.cv_px[c]:.3f}) | "
            f"{_px(lin[0])} | {_px(lin[1])} | {fit} | {linear_fold_rms(F, F, n, every, n_cam, M, d, sigma):.3f} | "
            f"{_px(before.fold_rms_px[c])} ({before.cv_px[c]:.3f}) |"
        )
        print(
            f"|  (mean log ratio to the best, its SE) | {cand.log_diff[0]:.3f}, "
            f"{cand.log_diff[1]:.3f} | | | | | | |"
        )
    return 0


def setup_variance(setup) -> np.ndarray:
    """(k,) the deviation's variance the plan assumes (the placement's zero)."""
    from selfcal.calibration.board.deviation import Deviation

    return Deviation().variance(setup.robot.joint_types)


def _px(v) -> str:
    return " ".join(f"{x:.3f}" for x in v)


if __name__ == "__main__":
    raise SystemExit(main())
