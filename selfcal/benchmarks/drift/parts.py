"""Benchmark: what limits the power of ``selfcal check`` against a mount shift (issue #29).

The drift benchmark (:mod:`selfcal.benchmarks.drift.images`) reports, beside the check's power,
the power of a test that knew the 0.2 mm mount shift's direction, from the noncentrality
``mu^T Sigma^-1 mu`` of the shift's linearised pixels ``mu`` under the check's covariance
``Sigma``. ``Sigma`` has four parts: the corner noise, the joint read-back noise (the robot file's
encoder table, :func:`selfcal.estimation.joint_report.encoder_sigma`), the calibration's model
error and the calibration's own uncertainty (its estimate's covariance carried to the new
views). This benchmark computes that noncentrality on the same simulated calibrations (the
analytic eye-in-hand board scenario, seeded by the draw) and 5 new views near their postures,
with the whole covariance and with one part left out, or one joint's read-back noise, and prints
per variant the median noncentrality over the checks and the mean power of the test that knew
the direction and of the one that knew only the mount's 3 translation axes (alpha = 0.01).
A part whose removal raises the power most is what keeps the check from finding the shift.

``--per-draw``: instead, the check itself per draw (:func:`per_draw`), with the 0.2 mm shift's
pixels put into the new views' corners: its statistic along the shift and on the mount's 3
translation axes under "unchanged" against their null (a standard normal and a chi-square of 3
degrees of freedom when the check's covariance is right where the shift shows), the shift's
signal (its pixels' RMS per corner, the noncentrality), the corner noise the calibration
estimated and its degrees of freedom, the check's verdicts and which of its tests found the
shift, beside the power of the tests told more (the direction; the size alone,
:func:`selfcal.calibration.drift.p_value.known_size_power`; the 3 axes, at the whole alpha and
at the share Bonferroni gives each of the check's tests): is it the data's limit or the test's?

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.drift.parts [--calibrations 6]
[--checks 10] [--noise-px 0.2] [--robot er4u-paper] [--per-draw]``.
"""

from __future__ import annotations

import dataclasses
import sys
from collections import Counter

import numpy as np
from scipy.stats import chi2

from selfcal.benchmarks.board.accuracy_draw import SCENARIO, simulated_calibration
from selfcal.benchmarks.drift.image_checks import NEW_VIEWS, SPREAD_RAD, TOOL_SHIFT_M, read_joints
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.drift.covariance import change_information
from selfcal.calibration.drift.images import (
    ALPHA,
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    image_drift_check,
)
from selfcal.calibration.drift.p_value import known_change_power, known_size_power
from selfcal.calibration.drift.views import view_jacobians
from selfcal.errors import InternalError
from selfcal.io.target_toml import parse_target
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import load_robot
from selfcal.sim.analytic import project_board
from selfcal.target.boards import Board
from selfcal.threads import limit_threads

__all__ = ["main", "noncentralities", "per_draw", "per_draw_summary"]

TINY_RAD = 1e-12  # a joint's read-back noise left out (the views' covariance needs all joints)


def _variants(
    js: np.ndarray | None, wrist: tuple[int, int] | None
) -> dict[str, tuple[np.ndarray | None, bool, bool]]:
    """Per variant: (joint read-back noise (n,) rad or None, model error kept, estimate's
    covariance kept); ``wrist``: the 0-based joints of a differential wrist, or None."""
    out: dict[str, tuple[np.ndarray | None, bool, bool]] = {
        "the check's covariance": (js, True, True),
        "without the joint read-back noise": (None, True, True),
        "without the model error": (js, False, True),
        "without the calibration's uncertainty": (js, True, False),
        "the corner noise alone": (None, False, False),
    }
    for j in range(0 if js is None else len(js)):
        assert js is not None
        one = js.copy()
        one[j] = TINY_RAD
        out[f"without joint {j + 1}'s read-back noise"] = (one, True, True)
    if js is not None and wrist is not None:
        both = js.copy()
        both[list(wrist)] = TINY_RAD
        joints = f"{wrist[0] + 1} and {wrist[1] + 1}"
        out[f"without the differential wrist's (joints {joints}) read-back noise"] = (
            both, True, True)  # fmt: skip
    return out


def _calibration(sigma_px: float, seed: int, robot: str | None) -> tuple:
    """The simulated calibration of draw ``seed`` at ``sigma_px`` (eye-in-hand, ``robot`` or the
    scenario's): the calibration, its truth, the robot, the board, the error model and the
    check's estimate covariance."""
    cal, truth = simulated_calibration(sigma_px, seed, scenario_file=SCENARIO, robot=robot)
    board = parse_target(cal.target, "calibration.json: target")
    assert isinstance(board, Board)
    em = calibration_error_model(cal, "calibration.json")
    return cal, truth, load_robot(cal.robot_model), board, em, estimate_covariance(cal, em)


def noncentralities(sigma_px: float, seed: int, checks: int, robot: str | None) -> dict:
    """Per variant (:func:`_variants`) the noncentralities of ``checks`` random 0.2 mm mount
    shifts, each over 5 new views, on the calibration of draw ``seed`` at ``sigma_px``."""
    cal, truth, arm, board, em, C = _calibration(sigma_px, seed, robot)
    assert cal.bounds is not None
    no_error = dataclasses.replace(em, model_error_m=0.0, model_error_rad=0.0)
    js_deg = cal.bounds.joint_sigma_deg
    js = None if js_deg is None else np.radians(np.asarray(js_deg, float))
    variants = _variants(js, None if arm.encoder is None else arm.encoder.differential)
    T_board = np.asarray((truth.board or {})["T_world_board"], float)
    q_cal = np.array([f.joints_rad for f in truth.frames])
    rng = np.random.default_rng(seed + 7000)
    n = q_cal.shape[1]
    out: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(checks):
        u = rng.normal(size=3)
        shift = TOOL_SHIFT_M * u / np.linalg.norm(u)
        views: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for _ in range(10_000):
            if len(views) == NEW_VIEWS:
                break
            q = q_cal[rng.integers(len(q_cal))] + rng.uniform(-SPREAD_RAD, SPREAD_RAD, n)
            T_cam = fk_tool(truth.true_model, q[None])[0]
            got = project_board(T_cam, truth.intrinsics_left, board, T_board,
                                pixel_sigma=sigma_px, rng=rng)  # fmt: skip
            if got:
                ids = np.array(sorted(got))
                views.append((read_joints(arm, q), board.points(ids),
                              np.concatenate([got[i] for i in ids])))  # fmt: skip
        if len(views) < NEW_VIEWS:
            raise InternalError(f"no {NEW_VIEWS} postures near the calibration's see the board")
        for key, (jsv, keep_error, keep_c) in variants.items():
            vj = [view_jacobians(em if keep_error else no_error, cal.cameras[0], q, X, uv,
                                 eye_to_hand=False, pixel_sigma_px=cal.bounds.pixel_sigma_px,
                                 joint_sigma_rad=jsv) for q, X, uv in views]  # fmt: skip
            mean = [dataclasses.replace(v, r=v.tool[:, :3] @ shift) for v in vj]
            cv = C if keep_c else np.zeros_like(C)
            out[key].append(float(image_drift_check(cv, mean, eye_to_hand=False).statistic))
    return out


def _tests(C: np.ndarray, views: list) -> dict[str, float]:
    """By name the p-value of each of the check's tests of ``views`` (the omnibus and the
    directed tests of :func:`selfcal.calibration.drift.attribution.candidate_fits`, eye-in-hand),
    from the whitened Gram matrix of the candidates' columns and the residuals."""
    n = views[0].joints.shape[1]
    cols = {"camera": np.concatenate([v.cam for v in views]),
            "hand-eye translation": np.concatenate([v.tool[:, :3] for v in views]),
            "hand-eye rotation": np.concatenate([v.tool[:, 3:] for v in views]),
            "world translation": np.concatenate([v.world[:, :3] for v in views]),
            "world rotation": np.concatenate([v.world[:, 3:] for v in views])}  # fmt: skip
    cols |= {f"joint {j + 1}": np.concatenate([v.joints[:, j : j + 1] for v in views])
             for j in range(n)}  # fmt: skip
    r = np.concatenate([v.r for v in views])
    M = change_information(C, views, np.concatenate([*cols.values(), r[:, None]], axis=1))
    out = {"omnibus": float(chi2.sf(M[-1, -1], len(r)))}
    at = 0
    for key, G in cols.items():
        S = slice(at, at + G.shape[1])
        at += G.shape[1]
        rank = int(np.linalg.matrix_rank(M[S, S]))
        if rank:
            out[key] = float(chi2.sf(M[S, -1] @ np.linalg.pinv(M[S, S]) @ M[S, -1], rank))
    return out


def _per_view(views: list) -> np.ndarray:
    """(2k, m n) every view's joint columns (px per rad), zero on the other views' rows."""
    at = np.cumsum([0] + [len(v.r) for v in views])
    n = views[0].joints.shape[1]
    out = np.zeros((at[-1], len(views) * n))
    for i, v in enumerate(views):
        out[at[i] : at[i + 1], i * n : (i + 1) * n] = v.joints
    return out


def _sigma(arm) -> np.ndarray | float:
    """(n,) the robot's joint read-back standard deviation (rad / m), 0 without an encoder
    table (its joints read exactly)."""
    return np.asarray(arm.encoder.read_back_sigma) if arm.encoder is not None else 0.0


def _rounded_power(weights: np.ndarray, lam2: float, q: np.ndarray, arm, rng,
                   draws: int = 20_000) -> float:  # fmt: skip
    """The power at :data:`ALPHA` of the test told the shift's direction (the whitened
    residuals' projection ``z`` on its pixels, noncentrality ``lam2``) with its critical value
    from the joint read-back's own distribution, the controller's rounded counts at the
    postures ``q`` (m, n) (bounded, not normal; the differential wrist's two motors included),
    instead of the normal one of the same variance; ``weights`` (m, n) ``z``'s change per rad
    of each view's joint read-back. The rest of ``z``'s unit variance (the corner noise, the
    calibration's estimate) stays normal. ``draws`` draws each for the critical value and the
    power (``rng``)."""
    rest = max(1.0 - float(np.sum((weights * _sigma(arm)) ** 2)), 0.0)

    def drawn() -> np.ndarray:
        z = rng.standard_normal(draws) * np.sqrt(rest)
        for qi, w in zip(q, weights, strict=True):  # a posture's rounding: its counts' fraction
            near = qi + rng.uniform(-0.01, 0.01, (draws, len(qi)))
            z += (read_joints(arm, near) - near) @ w
        return z

    crit = float(np.quantile(drawn(), 1.0 - ALPHA))
    return float(np.mean(drawn() + np.sqrt(lam2) > crit))


def per_draw(sigma_px: float, seed: int, checks: int, robot: str | None) -> list[dict]:
    """Per check of the calibration of draw ``seed`` at ``sigma_px`` (5 new views near its
    postures, as :func:`noncentralities` draws them, each seen unchanged and with the camera
    moved 0.2 mm on its mount in a random direction, the same joint read-back): the views'
    corners, the shift's pixels' RMS per corner (px) and noncentrality ``lam2``; under
    "unchanged" the whitened residuals' projection on the shift's direction ``z`` (standard
    normal when the check's covariance is right along it) and their chi-square on the mount's
    3 translation axes ``axes_null`` (3 degrees of freedom); the check's p-value unchanged and
    shifted, the name of the shifted check's test with the smallest p and the number of tests
    it combines; the power of the tests told the direction, the size, the 3 axes (module
    docstring); the calibration's corner noise (px) and its degrees of freedom (at least)."""
    cal, truth, arm, board, em, C = _calibration(sigma_px, seed, robot)
    assert cal.bounds is not None
    T_board = np.asarray((truth.board or {})["T_world_board"], float)
    q_cal = np.array([f.joints_rad for f in truth.frames])
    rng = np.random.default_rng(seed + 7000)
    n = q_cal.shape[1]
    noise_dof = 2 * cal.bounds.observations - cal.bounds.unknowns
    out: list[dict] = []
    for _ in range(checks):
        u = rng.normal(size=3)
        x = TOOL_SHIFT_M * u / np.linalg.norm(u)
        shift = np.eye(4)
        shift[:3, 3] = x
        q_new: list[np.ndarray] = []
        seen: dict[str, list] = {"unchanged": [], "shifted": []}
        for _ in range(10_000):
            if len(q_new) == NEW_VIEWS:
                break
            q = q_cal[rng.integers(len(q_cal))] + rng.uniform(-SPREAD_RAD, SPREAD_RAD, n)
            T_cam = fk_tool(truth.true_model, q[None])[0]
            got = [project_board(T, truth.intrinsics_left, board, T_board, pixel_sigma=sigma_px,
                                 rng=rng) for T in (T_cam, T_cam @ shift)]  # fmt: skip
            if all(got):
                for key, g in zip(seen, got, strict=True):
                    ids = np.array(sorted(g))
                    seen[key].append((len(q_new), board.points(ids),
                                      np.concatenate([g[i] for i in ids])))  # fmt: skip
                q_new.append(q)
        if len(q_new) < NEW_VIEWS:
            raise InternalError(f"no {NEW_VIEWS} postures near the calibration's see the board")
        qs = read_joints(arm, np.array(q_new))
        vj = {k: calibration_views(cal, em, qs, v) for k, v in seen.items()}
        G = np.concatenate([v.tool[:, :3] for v in vj["unchanged"]])
        r = np.concatenate([v.r for v in vj["unchanged"]])
        joints = _per_view(vj["unchanged"])
        # F, y = G^T Sigma^-1 r, and G^T Sigma^-1 of every view's joint columns
        M = change_information(C, vj["unchanged"], np.c_[G, r, joints])
        F, y = M[:3, :3], M[:3, 3]
        lam2 = float(x @ F @ x)
        weights = (x @ M[:3, 4:]).reshape(NEW_VIEWS, n) / np.sqrt(lam2)
        checked = {k: image_drift_check(C, v, eye_to_hand=False) for k, v in vj.items()}
        views = vj["unchanged"]
        mu = G @ x
        tests = _tests(C, vj["shifted"])
        out.append({
            "corners": len(r) // 2, "signal_px": float(np.sqrt(np.sum(mu**2) / (len(r) // 2))),
            "lam2": lam2, "z": float(x @ y) / np.sqrt(lam2),
            "axes_null": float(y @ np.linalg.solve(F, y)),
            "p_unchanged": checked["unchanged"].p_value, "p_shifted": checked["shifted"].p_value,
            "smallest": min(tests, key=tests.__getitem__), "tests": len(tests),
            "told_direction": float(known_change_power(lam2, ALPHA)),
            "told_direction_rounded": _rounded_power(weights, lam2, np.array(q_new), arm,
                                                     np.random.default_rng([seed, len(out)])),
            "read_back_share": float(np.sum((weights * _sigma(arm)) ** 2)),
            "told_size": known_size_power(F, x, ALPHA),
            "told_axes": float(known_change_power(lam2, ALPHA, dof=3)),
            "axes_bonferroni": float(known_change_power(lam2, ALPHA / len(tests), dof=3)),
            "noise_px": cal.bounds.pixel_sigma_px, "noise_dof": noise_dof,
            "views": len(views),
        })  # fmt: skip
    return out


def per_draw_summary(rows: list[dict], label: str) -> str:
    """The Markdown table of :func:`per_draw`'s ``rows`` (``label`` names the run)."""
    col = {k: np.array([r[k] for r in rows]) for k in rows[0] if k != "smallest"}
    q = lambda k: " / ".join(f"{v:.3g}" for v in np.quantile(col[k], [0.1, 0.5, 0.9]))  # noqa: E731
    mean = lambda k: f"{100 * np.mean(col[k]):.1f} %"  # noqa: E731
    found = Counter(r["smallest"] for r in rows if r["p_shifted"] < ALPHA)
    lines = [
        ("checks (5 new views each)", f"{len(rows)}"),
        ("corners per check: 10th / 50th / 90th percentile", q("corners")),
        ("the shift's pixels, RMS per corner (px): percentiles", q("signal_px")),
        ("its noncentrality mu^T Sigma^-1 mu: percentiles", q("lam2")),
        ("unchanged, along the shift: mean / variance (0 / 1 if the covariance is right)",
         f"{np.mean(col['z']):.3f} / {np.var(col['z']):.3f}"),
        ("unchanged, on the mount's 3 translation axes: mean / variance (3 / 6)",
         f"{np.mean(col['axes_null']):.2f} / {np.var(col['axes_null']):.2f}"),
        ("the calibration's corner noise (px): min / max; its degrees of freedom, at least",
         f"{col['noise_px'].min():.4f} / {col['noise_px'].max():.4f}; "
         f"{int(col['noise_dof'].min())}"),
        ("the check: 'changed' on unchanged data / the shift found",
         f"{100 * np.mean(col['p_unchanged'] < ALPHA):.1f} % / "
         f"{100 * np.mean(col['p_shifted'] < ALPHA):.1f} %"),
        ("the shifts found, by the check's test with the smallest p",
         ", ".join(f"{k} {v}" for k, v in found.most_common())),
        ("a test told the direction / the size alone / the 3 axes (alpha) / the 3 axes at alpha "
         f"over the check's {int(col['tests'][0])} tests",
         " / ".join(mean(k) for k in ("told_direction", "told_size", "told_axes",
                                      "axes_bonferroni"))),
        ("the joint read-back's share of the noise along the shift: percentiles",
         q("read_back_share")),
        ("the test told the direction with the read-back's rounded counts (bounded) in its "
         "critical value, not their normal distribution", mean("told_direction_rounded")),
        ("checks where even the test told the direction has less than 95 % power",
         f"{100 * np.mean(col['told_direction'] < 0.95):.0f} %"),
    ]  # fmt: skip
    return f"| {label} | |\n|---|---|\n" + "\n".join(f"| {k} | {v} |" for k, v in lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread) and print one line per variant (``--per-draw``:
    :func:`per_draw_summary`)."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--calibrations", type=int, default=6, help="draws (default 6)")
    ap.add_argument("--checks", type=int, default=10, help="per calibration (default 10)")
    ap.add_argument("--noise-px", type=float, default=0.2, help="pixel noise (default 0.2)")
    ap.add_argument("--robot", default=None, help="the scenario's robot replaced (default ER-4u)")
    ap.add_argument("--per-draw", action="store_true",
                    help="the check itself per draw against its null and the bounds")  # fmt: skip
    args = ap.parse_args(argv)
    if args.per_draw:
        drawn = [row for seed in range(1, args.calibrations + 1)
                 for row in per_draw(args.noise_px, seed, args.checks, args.robot)]  # fmt: skip
        print(per_draw_summary(drawn, f"{args.robot or 'er4u-paper'}, eye-in-hand, "
                               f"{args.noise_px:g} px, {args.calibrations} calibrations"))  # fmt: skip
        return 0
    rows: dict[str, list[float]] = {}
    for seed in range(1, args.calibrations + 1):
        for key, values in noncentralities(args.noise_px, seed, args.checks, args.robot).items():
            rows.setdefault(key, []).extend(values)
    print(f"| covariance ({args.noise_px:g} px, {args.calibrations} calibrations x "
          f"{args.checks} checks) | median noncentrality | test knowing the direction | "
          "knowing its 3 axes |\n|---|---|---|---|")  # fmt: skip
    for key, values in rows.items():
        lam2 = np.array(values)
        print(f"| {key} | {np.median(lam2):.1f} | "
              f"{100 * np.mean(known_change_power(lam2, ALPHA)):.1f} % | "
              f"{100 * np.mean(known_change_power(lam2, ALPHA, dof=3)):.1f} % |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
