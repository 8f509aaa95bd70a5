"""Benchmark: a real calibration's drift-check prediction on its own folds, and the held
deviation's share and the per-view misfit's scale estimated together from them (issue #29,
docs/real-data.md).

The check predicts a new view (:mod:`selfcal.calibration.drift.images`) with the held
parameters' deviation at the share ``c`` of the prior the folds showed (its upper bound,
:mod:`selfcal.calibration.board.held_prior`; one error shared by every view) and the per-view
misfit its own frames show (:mod:`selfcal.calibration.board.view_jitter`; each view's own). The
frames' residuals hold the deviation's part too, so it is counted twice; taking it out of either
alone makes the check reject the unchanged held-out group (``drift_real_deviation``).

Here each fold of the calibration (the chosen candidate fitted without one arm configuration,
:func:`selfcal.calibration.board.fold_fits.fold_bounds`: the folds that count, as
the accuracy block's) is the calibration and its held-out
frames the new views: what the check would predict for them (the fold's own covariance, the
deviation at share ``c``, the calibration's per-view misfit scaled by ``a``, its camera misfit,
white and joint read-back noise, each view's own white noise where above the calibration's as
the check gives it; no model error: both real sets have none) against their residuals: first
each fold's chi-square, its best directed test and each view's own white noise and p alone
with one white noise for every view, as the check was, and with each view's own (what drives
a fold's verdict). It prints the predicted / measured RMS per fold and pooled at the calibration's
``(c, 1)``; then ``(c, a)`` solved from the folds' residual energy in the span of the
deviation's pixels and outside it (two moments, two unknowns; the span's rank cut at a relative
eigenvalue ``tol``, three of them), the folds' ratios there, and the check of NEW with it;
``--grid``: each fold's check over a grid of ``(c, a)``. ``--shared``: each fold's held-out
configuration's one error shared by its views, a twist of the chain's world (eye-in-hand the
board's pose) fitted to them, and each fold's check with such an error of the size the other
folds show (isotropic in translation and in rotation, net of each fit's own variance) added to
its covariance: whether the folds' false alarms are an error shared by a configuration's views.
``--sandwich``: each fold's check with its estimate covariance's white-noise part (the corner
noise ``s``, the bounds', on every pixel alike) replaced by the sandwich of its training frames
under the noise the check gives a view (:func:`sandwich_excess`): whether the folds' false
alarms are the per-view misfit the fit averaged as white noise; then NEW checked against CAL
(and the files ``--also``: CAL's with a change written into them, as the real tier's) as is and
with CAL's own frames' sandwich in the covariance the check reads (:func:`check_with`).

Run: ``uv run python -m selfcal.benchmarks.drift.real_folds CAL NEW`` (CAL the folder of
``selfcal calibrate``, NEW a folder of ``selfcal import``; the real tier's, docs/real-data.md).
A minute: the calibration runs again.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from selfcal.benchmarks.drift.folds import Fold, folds_of, pose_misfit, sandwich_excess
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.accuracy import model_error_of
from selfcal.calibration.board.accuracy import ORIENTATION, POSITION, pose_error_terms
from selfcal.calibration.board.evaluate import held_out_views
from selfcal.calibration.board.view_jitter import psd_part
from selfcal.calibration.drift import images
from selfcal.calibration.drift.fold_error import fold_excess
from selfcal.calibration.drift.images import (
    ViewNoise,
    calibration_error_model,
    calibration_views,
    check_images,
    estimate_covariance,
    image_drift_check,
    view_noise,
)
from selfcal.calibration.drift.verdict import ImageDriftCheck
from selfcal.calibration.drift.views import ViewJacobians, tool_pose_error, view_white_px
from selfcal.calibration.whitened import whitened_rows, with_whitened
from selfcal.io.board_calibration import BoardCalibrationResult, read_board_calibration
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.threads import limit_threads

__all__ = [
    "Fold",
    "check_with",
    "excess_without",
    "fold_covariance",
    "folds_of",
    "joint_moments",
    "main",
    "pose_misfit",
    "ratios",
    "sandwich_excess",
    "shared_check",
    "shared_twist",
]

GRID_C, GRID_A = (0.0, 0.01, 0.05, 0.2, 1.0), (0.5, 1.0, 2.0, 5.0)
"""``--grid``: the shares ``c`` and misfit scales ``a`` at which each fold's check is printed."""
TOLERANCES = (1e-2, 1e-3, 1e-4)
"""The relative eigenvalues at which the deviation's pixel span is cut (:func:`joint_moments`)."""


def excess_without(folds: list[Fold], left: int | None,
                   whitened: bool = True) -> tuple[float, float]:  # fmt: skip
    """The folds' error at the configurations they left out (per coordinate, m and rad:
    :func:`selfcal.calibration.drift.fold_error.fold_excess`, the check's second null) from the
    held-out frames of every fold but ``left`` (its index; None: all of them, the calibration's
    own figure). Without ``left``'s own frames it is out of sample for that fold's check: its
    own miss does not size the error that may excuse it. ``whitened``: each row in its own
    metric (:func:`selfcal.calibration.whitened.whitened_excess`, the block's figure), else the
    squared norms' excess over isotropic standard errors (the block's before it)."""
    h = [f.tool for i, f in enumerate(folds) if i != left and f.tool is not None]
    if not h:
        return 0.0, 0.0
    pos, rot = (list(zip(*(pose_error_terms(x, b) for x in h), strict=True))
                for b in (POSITION, ORIENTATION))  # fmt: skip
    me = model_error_of(pos[0], pos[1], pos[2], (rot[0], rot[1], rot[2]), folds=len(h),
                        failed=0, noise_what="")  # fmt: skip
    if me is not None and whitened:  # as the accuracy block gives it (board/accuracy.py)
        e, V, between = whitened_rows(h)
        me = with_whitened(me, e, V, POSITION, ORIENTATION, between)
    return fold_excess({"model_error": me.to_json()} if me is not None else None)


def fold_covariance(fold: Fold, c: float, a: float) -> np.ndarray:
    """(n, n) px^2 what the check predicts for the fold's stacked views with the deviation at the
    share ``c`` of the prior and the per-view pose misfit scaled by ``a``."""
    H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in fold.views])
    S = H @ (fold.C0 + c * fold.V) @ H.T
    at = 0
    for v in fold.at(a):
        k = len(v.r)
        S[at : at + k, at : at + k] += v.local
        at += k
    return S


def ratios(folds: list[Fold], c: float, a: float) -> tuple[list[float], float]:
    """The predicted / measured RMS of each fold's held-out pixels and of them all pooled at
    ``(c, a)`` (:func:`fold_covariance`)."""
    pred = [float(np.trace(fold_covariance(f, c, a))) for f in folds]
    meas = [float(sum(v.r @ v.r for v in f.views)) for f in folds]
    each = [float(np.sqrt(p / m)) for p, m in zip(pred, meas, strict=True)]
    return each, float(np.sqrt(sum(pred) / sum(meas)))


def joint_moments(folds: list[Fold], tol: float) -> tuple[float, float]:
    """``(c, a)`` that predict the folds' summed residual energy both in the span of the
    deviation's pixels ``H V H^T`` (its eigenvectors above ``tol`` times its largest
    eigenvalue, per fold) and outside it: two linear equations in ``c`` and ``a``."""
    lhs, rhs = np.zeros((2, 2)), np.zeros(2)
    for f in folds:
        H = np.concatenate([np.concatenate([v.kin, v.cam], axis=1) for v in f.views])
        r = np.concatenate([v.r for v in f.views])
        D = H @ f.V @ H.T
        w, U = np.linalg.eigh(D)
        Uk = U[:, w > tol * w.max()]
        base = fold_covariance(f, 0.0, 0.0)
        M = fold_covariance(f, 0.0, 1.0) - base

        def energy(X: np.ndarray, Uk: np.ndarray = Uk) -> tuple[float, float]:
            inside = float(np.trace(Uk.T @ X @ Uk))  # in the span; outside: the rest
            return inside, float(np.trace(X)) - inside

        for j, (d, m, b, e) in enumerate(
            zip(energy(D), energy(M), energy(base), energy(np.outer(r, r)), strict=True)
        ):
            lhs[j] += [d, m]
            rhs[j] += e - b
    c, a = np.linalg.solve(lhs, rhs)
    return float(c), float(a)


def shared_twist(fold: Fold, c: float) -> tuple[np.ndarray, np.ndarray]:
    """(6,) m, rad the twist of the chain's world shared by the fold's held-out views that fits
    their residuals best under the check's covariance at the share ``c`` (generalised least
    squares), and its (6, 6) covariance under that covariance."""
    S = fold_covariance(fold, c, 1.0)
    W = np.concatenate([v.world for v in fold.views])
    r = np.concatenate([v.r for v in fold.views])
    SW = np.linalg.solve(S, W)
    F = W.T @ SW
    return np.linalg.solve(F, SW.T @ r), np.linalg.inv(F)


def shared_check(fold: Fold, c: float, G: np.ndarray, *, eye_to_hand: bool) -> ImageDriftCheck:
    """The check of the fold's held-out views at the share ``c`` with a world twist of
    covariance ``G`` (6, 6) m^2, rad^2 shared by them added (as six more estimated parameters)."""
    p = fold.views[0].kin.shape[1]
    C = fold.C0 + c * fold.V
    keep = np.r_[0:p, p + 6 : len(C) + 6]
    Cn = np.zeros((len(C) + 6, len(C) + 6))
    Cn[np.ix_(keep, keep)] = C
    Cn[p : p + 6, p : p + 6] = G
    views = [dataclasses.replace(v, kin=np.concatenate([v.kin, v.world], axis=1))
             for v in fold.at(1.0)]  # fmt: skip
    return image_drift_check(Cn, views, eye_to_hand=eye_to_hand)


def _print_shared(folds: list[Fold], c: float, eye_to_hand: bool) -> None:
    """``--shared`` (module docstring)."""
    fits = [shared_twist(f, c) for f in folds]
    for i, (x, P) in enumerate(fits):
        sd = np.sqrt(np.diag(P)) * 1e3
        print(f"  fold {i + 1}: shared world twist {np.round(x[:3] * 1e3, 3)} mm "
              f"(sd {np.round(sd[:3], 3)}), {np.round(x[3:] * 1e3, 3)} mrad "
              f"(sd {np.round(sd[3:], 3)})")  # fmt: skip
    for i, f in enumerate(folds):
        others = [fits[j] for j in range(len(folds)) if j != i]
        t2, w2 = (float(np.mean([max(x[s] @ x[s] - np.trace(P[s, s]), 0.0) for x, P in others]))
                  / 3 for s in (slice(0, 3), slice(3, 6)))  # fmt: skip
        zero, res = (shared_check(f, c, G, eye_to_hand=eye_to_hand)
                     for G in (np.zeros((6, 6)), np.diag([t2] * 3 + [w2] * 3)))  # fmt: skip
        print(f"  fold {i + 1}: p {zero.p_value:.2g} ({zero.best}); with the other folds' "
              f"shared twist ({np.sqrt(t2) * 1e3:.3f} mm, {np.sqrt(w2) * 1e3:.3f} mrad) p "
              f"{res.p_value:.2g} ({res.best}), predicted/measured "
              f"{res.expected_rms_px / res.rms_px:.2f}")  # fmt: skip


def check_with(path: Path, new: Path, extra: np.ndarray | float) -> ImageDriftCheck:
    """The check of ``new`` against the calibration file ``path`` with ``extra`` (P, P) added
    to the estimate covariance it reads (negative eigenvalues of the sum set to 0)."""
    orig = images.estimate_covariance

    def more(cal: BoardCalibrationResult, em: ToolErrorModel) -> np.ndarray:
        return psd_part(orig(cal, em) + extra)

    images.estimate_covariance = more
    try:
        return images.check_images(path, new)
    finally:
        images.estimate_covariance = orig


def _print_sandwich(folds: list[Fold], c: float, eye_to_hand: bool) -> None:
    """``--sandwich`` (module docstring): each fold's check at the share ``c`` with and without
    its sandwich excess (negative eigenvalues of the sum set to 0)."""
    print("  the estimate covariance with the training frames' sandwich (--sandwich):")
    for i, f in enumerate(folds):
        assert f.excess is not None
        C = psd_part(f.C0 + c * f.V + f.excess)
        base = image_drift_check(f.C0 + c * f.V, f.at(1.0), eye_to_hand=eye_to_hand)
        res = image_drift_check(C, f.at(1.0), eye_to_hand=eye_to_hand)
        k = f.views[0].cam.shape[1]
        ratio = np.sqrt(np.diag(C)[-k:] / np.diag(f.C0 + c * f.V)[-k:])
        print(f"  fold {i + 1}: p {base.p_value:.2g} ({base.best}), predicted/measured "
              f"{base.expected_rms_px / base.rms_px:.2f}; with the sandwich p {res.p_value:.2g} "
              f"({res.best}), predicted/measured {res.expected_rms_px / res.rms_px:.2f}; the "
              f"camera's sd x {' '.join(f'{x:.2f}' for x in ratio)}")  # fmt: skip


def _print_fold_error(folds: list[Fold], used: float, cal: BoardCalibrationResult,
                      cal_dir: Path, new: Path) -> None:  # fmt: skip
    """Each fold's verdict as the check gives it (:func:`selfcal.calibration.drift.images.
    fold_recheck`), a failed fold tested again with the folds' error at the configurations they
    left out (:func:`selfcal.calibration.drift.fold_error.fold_excess`) sized two ways: from
    the other folds' held-out frames only (:func:`excess_without`: out of sample, the fold's
    own miss not in it; a stand-in for the fold's own folds, which are not fitted) and from
    CAL's block, every fold's own configuration in it (in sample: optimistic for the folds whose
    own miss is large, which then size the error that excuses them, though not a bound for each
    fold: leaving out a fold that missed less than the others raises it); then NEW's
    ``selfcal check`` against CAL."""
    counted = view_noise(cal).misfit_counted
    pos, rot = fold_excess(cal.accuracy) if counted else (0.0, 0.0)
    again_pos, again_rot = excess_without(folds, None) if counted else (0.0, 0.0)
    iso_pos, iso_rot = excess_without(folds, None, whitened=False) if counted else (0.0, 0.0)
    print(f"  the folds' error at left-out configurations, in sample (CAL's block, each fold's "
          f"own configuration in it): {pos * 1e3:.3f} mm, {np.degrees(rot):.3f} deg per coordinate (from these "
          f"folds again: {again_pos * 1e3:.3f} mm, {np.degrees(again_rot):.3f} deg; isotropic "
          f"{iso_pos * 1e3:.3f} mm, {np.degrees(iso_rot):.3f} deg)")  # fmt: skip

    def verdict(f: Fold, pos: float, rot: float) -> tuple[str, float]:
        m2 = np.r_[np.full(3, pos**2), np.full(3, rot**2)]
        wide = [dataclasses.replace(v, local=v.local + tool_pose_error(v.tool, v.B, m2))
                for v in f.at(1.0)]  # fmt: skip
        again = image_drift_check(f.C0 + used * f.V, wide, eye_to_hand=cal.eye_to_hand)
        return ("changed" if again.changed else "cannot tell"), again.p_value

    said, changed, iso = [], [0, 0], 0
    for i, f in enumerate(folds):
        first = image_drift_check(f.C0 + used * f.V, f.at(1.0), eye_to_hand=cal.eye_to_hand)
        if not first.changed:
            what = "cannot tell (noisier images)" if first.undecided else "unchanged"
            said.append(f"fold {i + 1} {what} (p {first.p_value:.2g})")
            continue
        out = excess_without(folds, i) if counted else (0.0, 0.0)
        old = excess_without(folds, i, whitened=False) if counted else (0.0, 0.0)
        (v_in, p_in), (v_out, p_out) = verdict(f, pos, rot), verdict(f, *out)
        v_old, p_old = verdict(f, *old)
        changed[0] += v_out == "changed"
        changed[1] += v_in == "changed"
        iso += v_old == "changed"
        said.append(f"fold {i + 1} p {first.p_value:.2g}; out of sample ({out[0] * 1e3:.3f} mm, "
                    f"{np.degrees(out[1]):.3f} deg) {v_out} (p {p_out:.2g}); in sample {v_in} "
                    f"(p {p_in:.2g}); out of sample isotropic ({old[0] * 1e3:.3f} mm, "
                    f"{np.degrees(old[1]):.3f} deg) {v_old} (p {p_old:.2g})")  # fmt: skip
    print(f"  with the folds' error at left-out configurations: {'; '.join(said)}")
    print(f"  false 'changed' of {len(folds)} folds: {changed[0]} with the folds' error out of "
          f"sample, {changed[1]} in sample (each fold's own miss in its error); {iso} out of "
          "sample with the squared norms' isotropic excess (the rule before the whitened one)")  # fmt: skip
    res = check_images(cal_dir, new)
    verdict_new = "changed" if res.changed else "cannot tell" if res.undecided else "unchanged"
    print(f"  selfcal check {cal_dir} {new}: {verdict_new}, p = {res.p_value:.2g}, with the folds' "
          f"error {res.fold_p_value:.2g}; predicted / measured {res.expected_rms_px:.3f} / "
          f"{res.rms_px:.3f} px")  # fmt: skip


def _pooled(v: ViewJacobians, white_px: float) -> ViewJacobians:
    """The new view ``v`` with the calibration's white noise ``white_px`` in place of its own
    (the check before :func:`selfcal.calibration.drift.views.view_white_px`)."""
    own = view_white_px(v.r, v.tool, v.cam, white_px)
    extra = 0.0 if own is None else own**2 - white_px**2
    return dataclasses.replace(v, local=v.local - extra * np.eye(len(v.r)))


def _print_evidence(folds: list[Fold], used: float, noise: ViewNoise, eye_to_hand: bool) -> None:
    """Each fold's check (at the share ``used``) with one white noise for every view (the
    calibration's, as the check was) and with each view's own where above it (as it is): the
    chi-square of all the residuals against its degrees of freedom, the combined p, the best
    change and each view's p alone; and each held-out view's own white corner noise (outside its
    pose span and the camera's directions, :func:`selfcal.calibration.drift.views.
    view_white_px`) against the calibration's: what drives a fold's verdict."""
    w = noise.pixel_sigma_px
    for i, f in enumerate(folds):
        C = f.C0 + used * f.V
        own = [view_white_px(v.r, v.tool, v.cam) for v in f.views]
        said = []
        for label, views in (("one white noise", [_pooled(v, w) for v in f.at(1.0)]),
                             ("each view's own", f.at(1.0))):  # fmt: skip
            res = image_drift_check(C, views, eye_to_hand=eye_to_hand)
            alone = [image_drift_check(C, [v], eye_to_hand=eye_to_hand).p_value for v in views]
            said.append(f"{label}: chi-square {res.statistic:.1f} on {res.dof}, p "
                        f"{res.p_value:.2g} (best {res.best}), each view alone p "
                        f"{' '.join(f'{p:.2g}' for p in alone)}")  # fmt: skip
        print(f"  fold {i + 1}: the views' own white noise "
              f"{' '.join('-' if x is None else f'{x:.3f}' for x in own)} px against the "
              f"calibration's {w:.3f}; {'; '.join(said)}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Print the folds' ratios, the joint estimate and NEW's check with it (module docstring)."""
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("calibration", type=Path, help="the folder of `selfcal calibrate`")
    ap.add_argument("new", type=Path, help="a folder of `selfcal import`: new views")
    ap.add_argument("--grid", action="store_true",
                    help="also each fold's check over c in 0-1 and a in 0.5-5")  # fmt: skip
    ap.add_argument("--shared", action="store_true",
                    help="also each fold's error shared by its views (module docstring)")  # fmt: skip
    ap.add_argument("--sandwich", action="store_true",
                    help="also each fold's check with its training frames' sandwich covariance "
                    "(module docstring)")  # fmt: skip
    ap.add_argument("--also", type=Path, nargs="*", default=[],
                    help="--sandwich: calibration files (CAL's with a change written into "
                    "them) also checked against NEW with CAL's own frames' sandwich")  # fmt: skip
    args = ap.parse_args(argv)
    limit_threads(1)
    path = args.calibration / "calibration.json"
    folds, V, E = folds_of(args.calibration)
    cal = read_board_calibration(path)
    em = calibration_error_model(cal, str(path))
    C = estimate_covariance(cal, em)
    used = float((cal.accuracy or {})["held_deviation"]["share"])
    h = held_out_views(cal, args.new, cameras=(cal.camera_names[0],))
    new = calibration_views(cal, em, h.q, [(f, X, uv) for _, f, _, _, X, uv in h.views])
    noise = view_noise(cal)
    misfit = [pose_misfit(noise, v.tool) for v in new]

    def line(label: str, c: float, a: float) -> None:
        each, pooled = ratios(folds, c, a)
        vs = [dataclasses.replace(v, local=v.local + (a - 1.0) * M)
              for v, M in zip(new, misfit, strict=True)]  # fmt: skip
        res = image_drift_check(C + (c - used) * V, vs, eye_to_hand=cal.eye_to_hand,
                                camera_names=cal.cameras[0].free)  # fmt: skip
        ps = [image_drift_check(f.C0 + c * f.V, f.at(a), eye_to_hand=cal.eye_to_hand).p_value
              for f in folds]  # fmt: skip
        print(f"  {label}: c = {c:.4g}, a = {a:.3g}; folds' predicted/measured RMS "
              f"{' '.join(f'{x:.2f}' for x in each)}, pooled {pooled:.2f}, their check's p "
              f"{' '.join(f'{x:.2g}' for x in ps)}; {args.new}: p = {res.p_value:.2g}, "
              f"predicted/measured {res.expected_rms_px / res.rms_px:.2f}")  # fmt: skip

    print(f"{len(folds)} folds of {args.calibration}")
    _print_evidence(folds, used, noise, cal.eye_to_hand)
    line("as the check predicts (the share used, the misfit as estimated)", used, 1.0)
    _print_fold_error(folds, used, cal, args.calibration, args.new)
    for tol in TOLERANCES:
        line(f"joint estimate (span cut at {tol:g})", *joint_moments(folds, tol))
    for c, a in ((c, a) for c in GRID_C for a in GRID_A) if args.grid else ():
        ps = [image_drift_check(f.C0 + c * f.V, f.at(a), eye_to_hand=cal.eye_to_hand).p_value
              for f in folds]  # fmt: skip
        print(f"  c = {c:g}, a = {a:g}: the folds' check p {' '.join(f'{x:.2g}' for x in ps)}, "
              f"predicted/measured pooled {ratios(folds, c, a)[1]:.2f}")  # fmt: skip
    if args.shared:
        print("  an error shared by each held-out configuration's views (--shared):")
        _print_shared(folds, used, cal.eye_to_hand)
    if args.sandwich:
        _print_sandwich(folds, used, cal.eye_to_hand)
        for f in (path, *args.also):
            for label, extra in (("as is", 0.0), ("with its own frames' sandwich", E)):
                res = check_with(f, args.new, extra)
                verdict = "changed" if res.changed else "unchanged"
                print(f"  {f} against {args.new} {label}: {verdict}, p = {res.p_value:.2g} "
                      f"({res.best}), predicted/measured {res.expected_rms_px / res.rms_px:.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
