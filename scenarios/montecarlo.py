"""``selfcal montecarlo --draws N --out DIR [--jobs 2]``: achieved error against the Cramer-Rao bound.

ONE truth -- the default scenario (``scenarios/paper.toml``) on the analytic path: perturbation
seed 1, trajectory seed 1 (the same calibration and validation postures), the same marker field --
and many noise draws (``[noise] seed`` = draw index): Gaussian corner noise, and, with ``dither``
(default), the encoder quantisation residue too: each draw moves the robot to the planned postures
plus a uniform random fraction of one encoder count (< 0.01 deg), so the read-back errors are a
fresh uniform draw with the variance the joint method's prior assumes, instead of the same
deterministic rounding errors in every draw (which would be a fixed, truth-like bias).

Every draw runs the two-stage calibration and the one-step refinement (``calib.calibrate``,
method "joint"; the two-stage result is the start) and records, for both methods, the validation
tool-tip RMS after rigid alignment (as ``selfcal report``) and every minimal MCPC parameter's error
in the reference-camera frame, together with the bounds of :mod:`calib.bounds` at the draw's
joint estimate with the *true* noise levels (``pixel_sigma``, encoder resolution).

Summary (``DIR/summary.md``, ``DIR/summary.json``, ``DIR/montecarlo.png``):

- tool tip: ``ratio = sqrt(mean_draws rms^2) / bound`` (an unbiased efficient estimator has 1);
- parameters: per parameter ``sqrt(mean_draws err^2) / bound``, then the median over the
  estimated parameters;
- 95 % intervals: bootstrap over draws (percentile), and for the tool tip also the interval an
  efficient estimator would show with this many draws (``rms^2`` is a weighted sum of chi-squares;
  Satterthwaite's effective degrees of freedom).

The collision check (:mod:`sim.collision`) and the optimal plan of a scenario
(:func:`scenarios.backends.plan_optimal`) are re-exported here for the plan comparison.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import sys
import tempfile
import time
import warnings
from concurrent.futures import FIRST_COMPLETED, wait
from pathlib import Path

import numpy as np

from calib.bounds import aligned_error_dof, cramer_rao, predicted_setup, setup_from_output
from calib.calibrate import _observations, calibrate, detect_dataset
from calib.dataset import Dataset, DatasetWriter
from calib.identify import express_in_frame, minimal_difference
from calib.joint_refine import encoder_sigma
from calib.mcpc import minimal_indices, param_is_angle
from calib.report import aligned_errors, tool_tips
from calib.robot_def import load_robot
from calib.trajectory import plan_postures
from calib.transforms import inv_pose
from scenarios.acquire import acquire
from scenarios.backends import open_robot, plan_dataset, plan_optimal, planning_inputs, sim_setup
from scenarios.config import load_scenario
from scenarios.parallel import worker_pool
from scenarios.plotting import pyplot
from sim.actual import read_truth
from sim.collision import collision_checker, collision_free

__all__ = [
    "draw_one",
    "run_montecarlo",
    "summarize",
    "collision_checker",
    "collision_free",
    "plan_optimal",
    "compare_plans",
    "planning_inputs",
    "predicted_bound",
    "run_plan_comparison",
    "register",
]

METHODS = ("joint", "two_stage")


# ------------------------------------------------------------------------------ one draw
def _scenario(settings: dict):
    return load_scenario(
        settings.get("config"),
        {
            "noise": {
                "render": False,
                "pixel_sigma": float(settings["pixel_sigma"]),
                "seed": int(settings["seed"]),
                "quantize_joints": bool(settings.get("quantize", True)),
            },
            "trajectory": {"poses": int(settings["poses"]), "seed": int(settings["traj_seed"])},
            "perturbation": {"seed": int(settings["perturb_seed"])},
        },
    )


def _acquire(settings: dict, root: Path):
    """The draw's dataset in ``root``: planned (or given) postures, dithered, analytic corners."""
    s = _scenario(settings)
    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    planned = info.planned_joints_deg
    if settings.get("joints_deg") is not None:
        planned = np.asarray(settings["joints_deg"], dtype=float)
    if settings.get("dither", True):
        rng = np.random.default_rng(int(settings["seed"]) + 104_729)
        cpd = np.asarray(setup.robot.counts_per_unit, dtype=float) * np.pi / 180.0
        planned = planned + rng.uniform(-0.5, 0.5, planned.shape) / cpd
        lo, hi = np.degrees(setup.robot.limits).T
        planned = np.clip(planned, lo, hi)
    info = dataclasses.replace(info, planned_joints_deg=planned)
    writer = DatasetWriter(root, info)
    robot, hooks = open_robot(s, root, setup)
    try:
        acquire(robot, writer, hooks=hooks)
    finally:
        robot.close()
    return s


def draw_one(settings: dict) -> dict:
    """One noise draw: acquire, calibrate (two-stage + joint), compare with truth and the bound.

    ``settings``: ``poses``, ``pixel_sigma``, ``seed`` (noise), ``traj_seed``, ``perturb_seed``,
    ``dither`` (bool), optionally ``joints_deg`` (planned postures to use instead of the
    scenario's plan), ``quantize``, ``config``. Returns a flat row (mm / deg); never raises: a
    failed draw has ``status = "failed: ..."``.
    """
    t0 = time.perf_counter()
    row: dict = {k: settings.get(k) for k in ("poses", "pixel_sigma", "seed", "dither")}
    row["plan"] = settings.get("plan", "random")
    try:
        with tempfile.TemporaryDirectory(prefix="selfcal-mc-") as d, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            root = Path(d) / "run"
            _acquire(settings, root)
            row.update(_evaluate(root, float(settings["pixel_sigma"])))
        row["status"] = "ok"
    except Exception as exc:  # noqa: BLE001 - a study records failures instead of stopping
        row["status"] = f"failed: {type(exc).__name__}: {str(exc)[:200]}"
    row["seconds"] = round(time.perf_counter() - t0, 3)
    return row


def _evaluate(root: Path, pixel_sigma: float) -> dict:
    out = calibrate(root, method="joint")
    ds = Dataset.open(root)
    robot = load_robot(ds.info.robot_model)
    truth = read_truth(root / "truth.json")
    qv = np.radians(ds.info.validation_joints_deg)
    p_true = tool_tips(truth.true_model, qv, truth.T_cam_tip)
    models = {"joint": out.model, "two_stage": out.identification.model}
    row: dict = {}
    for k, mdl in models.items():
        row[f"{k}_tip_rms_mm"] = aligned_errors(tool_tips(mdl, qv, truth.T_cam_tip), p_true)["rms"]
    row["nominal_tip_rms_mm"] = aligned_errors(
        tool_tips(truth.nominal_model, qv, truth.T_cam_tip), p_true
    )["rms"]
    row["joint_fx_err_px"] = out.joint.fx - truth.intrinsics_left.fx
    row["two_stage_fx_err_px"] = out.selfcal.fx - truth.intrinsics_left.fx
    # parameters in the reference-camera frame (the true one for the truth, like selfcal report)
    frames = {int(f["frame_index"]): f for f in truth.frames}
    idx = minimal_indices(out.model.joint_types)
    scale = np.where(param_is_angle(idx), 180.0 / np.pi, 1000.0)
    for k, mdl in models.items():
        ref = out.joint.ref_config if k == "joint" else out.selfcal.ref_config
        T = inv_pose(np.asarray(frames[int(ds.indices[ref])]["T_world_cam_left"]))
        err = minimal_difference(mdl, express_in_frame(truth.true_model, T, like=mdl)) * scale
        for name, e in zip(out.joint.names, err):
            row[f"{k}_err_{name}"] = float(e)
    # the bound at this draw's joint estimate, with the true noise levels
    obs = _observations(ds, detect_dataset(ds))
    q = np.radians(ds.joints_deg)
    s = setup_from_output(out, obs, q, robot, ds.info, pixel_sigma_px=pixel_sigma)
    cr = cramer_rao(s)
    row["bound_tip_rms_mm"] = 1000.0 * cr.aligned_tool_rms(qv, truth.T_cam_tip)
    row["dof_tip"] = aligned_error_dof(*cr.tool_points(qv, truth.T_cam_tip))
    two = dataclasses.replace(out, joint=None, model=out.identification.model)
    s2 = setup_from_output(two, obs, q, robot, ds.info, pixel_sigma_px=pixel_sigma)
    row["bound_tip_two_stage_mm"] = 1000.0 * cramer_rao(s2).aligned_tool_rms(qv, truth.T_cam_tip)
    row["bound_fx_px"] = cr.fx_std
    row["sigma_hat_px"] = out.joint.sigma_px
    row["outliers"] = out.joint.n_outliers
    for name, b in zip(cr.names, cr.std_ref * scale):
        row[f"bound_{name}"] = float(b) if np.isfinite(b) else None
        row[f"held_{name}"] = name in cr.held and not cr.held[name].startswith("gauge")
    return row


# ------------------------------------------------------------------------------ driver
def _map(fn, items: list, jobs: int, on_result=None) -> list:
    """``[fn(x) for x in items]`` in ``jobs`` spawned processes (one BLAS thread each)."""
    if jobs <= 1 or len(items) <= 1:
        out = []
        for x in items:
            out.append(fn(x))
            if on_result:
                on_result(out[-1])
        return out
    results: dict = {}
    with worker_pool(min(jobs, len(items))) as ex:
        futs = {ex.submit(fn, x): i for i, x in enumerate(items)}
        pending = set(futs)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                results[futs[f]] = f.result()
                if on_result:
                    on_result(results[futs[f]])
    return [results[i] for i in range(len(items))]


def run_montecarlo(
    draws: int,
    out: str | Path | None = None,
    *,
    poses: int = 30,
    pixel_sigma: float = 0.5,
    traj_seed: int = 1,
    perturb_seed: int = 1,
    dither: bool = True,
    plan: str = "random",
    joints_deg: np.ndarray | None = None,
    jobs: int = 2,
    first_seed: int = 1,
    quiet: bool = False,
) -> tuple[list[dict], dict]:
    """Run ``draws`` noise draws (seeds ``first_seed ..``); returns ``(rows, summary)``.

    With ``out``: writes ``runs.csv``, ``summary.json``, ``summary.md`` and ``montecarlo.png``
    there. ``joints_deg``: planned postures to use instead of the scenario's random plan (e.g.
    from :func:`plan_optimal`; ``plan`` names them in the output).
    """
    base = {
        "poses": poses if joints_deg is None else len(joints_deg),
        "pixel_sigma": pixel_sigma,
        "traj_seed": traj_seed,
        "perturb_seed": perturb_seed,
        "dither": dither,
        "plan": plan,
        "joints_deg": None if joints_deg is None else np.asarray(joints_deg).tolist(),
    }
    items = [{**base, "seed": first_seed + i} for i in range(draws)]
    t0 = time.perf_counter()
    k = [0]

    def say(row):
        k[0] += 1
        if not quiet:
            msg = (
                f"joint {row['joint_tip_rms_mm']:.3f} mm, two-stage {row['two_stage_tip_rms_mm']:.3f}"
                f" mm, bound {row['bound_tip_rms_mm']:.3f} mm"
                if row["status"] == "ok"
                else row["status"]
            )
            print(
                f"  [{k[0]}/{draws}] seed {row['seed']}: {msg} ({row['seconds']:.1f} s)",
                file=sys.stderr,
            )

    rows = _map(draw_one, items, max(1, int(jobs)), say)
    summary = summarize(rows)
    summary["settings"] = {k: v for k, v in base.items() if k != "joints_deg"}
    summary["seconds"] = round(time.perf_counter() - t0, 1)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        _write_csv(rows, out / "runs.csv")
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
        (out / "summary.md").write_text(summary_markdown(summary))
        plot(rows, summary, out / "montecarlo.png")
    return rows, summary


def _write_csv(rows: list[dict], path: Path) -> None:
    cols: list[str] = []
    for r in rows:
        cols += [c for c in r if c not in cols]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else r.get(c) for c in cols])


# ------------------------------------------------------------------------------ statistics
def _boot(values: np.ndarray, stat, n: int = 2000, seed: int = 0) -> tuple[float, float]:
    """95 % percentile bootstrap interval of ``stat`` over the rows of ``values``."""
    rng = np.random.default_rng(seed)
    k = len(values)
    s = np.array([stat(values[rng.integers(0, k, k)]) for _ in range(n)])
    return float(np.percentile(s, 2.5)), float(np.percentile(s, 97.5))


def efficient_ratio_interval(n_draws: int, dof: float, level: float = 0.95) -> tuple[float, float]:
    """Interval of ``sqrt(mean of n_draws values of rms^2) / bound`` for an unbiased efficient
    estimator when ``rms^2 / bound^2 ~ chi2(dof) / dof`` (Satterthwaite): central ``level``."""
    from scipy.stats import chi2  # ~1 s to import (python -X importtime); only this needs it

    nu = n_draws * dof
    a = (1 - level) / 2
    return float(np.sqrt(chi2.ppf(a, nu) / nu)), float(np.sqrt(chi2.ppf(1 - a, nu) / nu))


def summarize(rows: list[dict]) -> dict:
    """Ratios achieved / bound with 95 % intervals for both methods (see the module docstring)."""
    ok = [r for r in rows if r.get("status") == "ok"]
    res: dict = {"draws": len(rows), "ok": len(ok), "failed": len(rows) - len(ok)}
    if not ok:
        return res
    bound = float(np.median([r["bound_tip_rms_mm"] for r in ok]))
    names = [c[len("held_") :] for c in ok[0] if c.startswith("held_")]
    est = [n for n in names if ok[0][f"bound_{n}"] is not None and not ok[0][f"held_{n}"]]
    pb = np.array([[r[f"bound_{n}"] for n in est] for r in ok], dtype=float)
    pbound = np.median(pb, axis=0)
    res["tool_tip_bound_mm"] = bound
    res["nominal_tip_rms_mm"] = float(np.median([r["nominal_tip_rms_mm"] for r in ok]))
    res["bound_spread"] = float(np.ptp([r["bound_tip_rms_mm"] for r in ok]) / bound)
    dof = [r["dof_tip"] for r in ok if r.get("dof_tip") is not None]
    res["tool_tip_dof"] = float(np.median(dof)) if dof else None
    res["efficient_tip_ratio_ci95"] = (
        efficient_ratio_interval(len(ok), res["tool_tip_dof"]) if dof else None
    )
    for m in METHODS:
        tip2 = np.array([r[f"{m}_tip_rms_mm"] ** 2 for r in ok])
        ratio = float(np.sqrt(tip2.mean()) / bound)
        ci = _boot(tip2[:, None], lambda v: np.sqrt(v.mean()) / bound)
        E = np.array([[r[f"{m}_err_{n}"] for n in est] for r in ok], dtype=float)

        def med_ratio(e, pbound=pbound):
            return float(np.median(np.sqrt(np.mean(e**2, axis=0)) / pbound))

        per = np.sqrt(np.mean(E**2, axis=0)) / pbound
        bias = np.abs(E.mean(axis=0)) / (pbound / np.sqrt(len(ok)))
        res[m] = {
            "tool_tip_rms_mm": float(np.sqrt(tip2.mean())),
            "tool_tip_ratio": ratio,
            "tool_tip_ratio_ci95": ci,
            "param_ratio_median": med_ratio(E),
            "param_ratio_median_ci95": _boot(E, med_ratio),
            "param_ratios": {n: float(v) for n, v in zip(est, per)},
            "param_bias_z": {n: float(v) for n, v in zip(est, bias)},
            "fx_ratio": float(
                np.sqrt(np.mean([r[f"{m}_fx_err_px"] ** 2 for r in ok]))
                / np.median([r["bound_fx_px"] for r in ok])
            ),
        }
    # interval an efficient estimator would give with this many draws (per-parameter: chi2(1))
    res["efficient_param_ratio_ci95_single"] = efficient_ratio_interval(len(ok), 1.0)
    return res


def summary_markdown(s: dict) -> str:
    if not s.get("ok"):
        return f"# Monte Carlo\n\nno successful draw ({s.get('failed', 0)} failed)\n"
    st = s.get("settings", {})
    lines = [
        "# Monte Carlo: achieved error against the Cramer-Rao bound",
        "",
        f"Default scenario, analytic path, one truth (perturbation seed {st.get('perturb_seed')}, "
        f"trajectory seed {st.get('traj_seed')}, plan {st.get('plan')}, {st.get('poses')} poses), "
        f"{s['ok']} noise draws ({s['failed']} failed), corner noise {st.get('pixel_sigma')} px, "
        f"read-back dithered: {st.get('dither')}.",
        "",
        f"Tool-tip bound (aligned RMS over the validation postures): "
        f"{s['tool_tip_bound_mm']:.4f} mm (spread over draws {100 * s['bound_spread']:.1f} %); "
        f"nominal model {s['nominal_tip_rms_mm']:.3f} mm.",
        "",
        "| method | tool-tip RMS (mm) | tool tip / bound | 95 % CI | median parameter / bound "
        "| 95 % CI | fx / bound |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in METHODS:
        r = s[m]
        lines.append(
            f"| {m.replace('_', '-')} | {r['tool_tip_rms_mm']:.4f} | {r['tool_tip_ratio']:.3f} | "
            f"{r['tool_tip_ratio_ci95'][0]:.3f} - {r['tool_tip_ratio_ci95'][1]:.3f} | "
            f"{r['param_ratio_median']:.3f} | {r['param_ratio_median_ci95'][0]:.3f} - "
            f"{r['param_ratio_median_ci95'][1]:.3f} | {r['fx_ratio']:.3f} |"
        )
    lo, hi = s["efficient_param_ratio_ci95_single"]
    eff = s.get("efficient_tip_ratio_ci95")
    tip = (
        f" The tool-tip ratio of an efficient estimator would lie in {eff[0]:.3f} - {eff[1]:.3f}"
        f" (chi-square with {s['ok']} x {s['tool_tip_dof']:.1f} effective dof)."
        if eff
        else ""
    )
    lines += [
        "",
        "Ratios are sqrt(mean over draws of error^2) / bound; intervals are 95 % percentile "
        f"bootstrap over draws. One parameter's ratio of an efficient estimator would lie in "
        f"{lo:.3f} - {hi:.3f} (chi-square, {s['ok']} draws).{tip}",
        "",
        "Per-parameter ratios (joint / two-stage) and |mean error| / (bound / sqrt(draws)) of the "
        "joint method (> 3: a bias shows):",
        "",
        "| parameter | joint | two-stage | joint bias z |",
        "|---|---|---|---|",
    ]
    for n, v in s["joint"]["param_ratios"].items():
        lines.append(
            f"| {n} | {v:.3f} | {s['two_stage']['param_ratios'][n]:.3f} | "
            f"{s['joint']['param_bias_z'][n]:.2f} |"
        )
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], s: dict, path: Path) -> None:
    plt = pyplot()

    ok = [r for r in rows if r.get("status") == "ok"]
    if not ok:
        return
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    b = s["tool_tip_bound_mm"]
    bins = np.linspace(0, max(max(r["two_stage_tip_rms_mm"] for r in ok), 3 * b), 30)
    for m, c in (("joint", "tab:red"), ("two_stage", "tab:blue")):
        a1.hist(
            [r[f"{m}_tip_rms_mm"] for r in ok],
            bins=bins,
            alpha=0.55,
            color=c,
            label=f"{m.replace('_', '-')} (ratio {s[m]['tool_tip_ratio']:.2f})",
        )
    a1.axvline(b, color="k", ls="--", label=f"Cramer-Rao bound {b:.3f} mm")
    a1.set_xlabel("validation tool-tip RMS after alignment (mm)")
    a1.set_ylabel("draws")
    a1.set_title(f"{len(ok)} noise draws, one truth")
    a1.legend(fontsize=8)
    names = list(s["joint"]["param_ratios"])
    x = np.arange(len(names))
    a2.bar(
        x - 0.2, [s["joint"]["param_ratios"][n] for n in names], 0.4, color="tab:red", label="joint"
    )
    a2.bar(
        x + 0.2,
        [s["two_stage"]["param_ratios"][n] for n in names],
        0.4,
        color="tab:blue",
        label="two-stage",
    )
    a2.axhline(1.0, color="k", ls="--", lw=1)
    a2.set_yscale("log")
    a2.set_xticks(x, names, rotation=90, fontsize=7)
    a2.set_ylabel("RMS error / bound")
    a2.set_title("parameters (reference-camera frame)")
    a2.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------------ bounds of plans
def predicted_bound(s, q: np.ndarray) -> dict:
    """The Cramer-Rao bounds (mm, deg) of a plan ``q`` (m, n) rad before acquisition, from the
    simulator's actual robot and marker field (:func:`calib.bounds.predicted_setup`): the
    validation tool-tip RMS and the median parameter bound."""
    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    fld = setup.field
    st = predicted_setup(
        setup.actual,
        q,
        setup.T_left_right,
        setup.intrinsics,
        fld.ids,
        fld.corners_world(),
        fld.T_world_marker[:, :3, 2],
        tuple(int(i) for i in fld.scale_ids),
        s.target.scale_length_mm / 1000,
        pixel_sigma_px=s.noise.pixel_sigma,
        joint_sigma=encoder_sigma(setup.robot) if s.noise.quantize_joints else None,
    )
    cr = cramer_rao(st)
    qv = np.radians(info.validation_joints_deg)
    idx = minimal_indices(cr.model.joint_types)
    sc = np.where(param_is_angle(idx), 180 / np.pi, 1000.0)
    b = cr.std_ref * sc
    est = np.array([n not in cr.held for n in cr.names])
    return {
        "tool_tip_rms_mm": 1000 * cr.aligned_tool_rms(qv, inv_pose(setup.robot.T_flange_cam)),
        "median_param_bound": float(np.median(b[est])),
        "param_bounds": dict(zip(cr.names, b.tolist())),
        "fx_px": cr.fx_std,
        "observations": cr.n_observations,
    }


def compare_plans(
    counts=(10, 20, 30), *, seeds=(1, 2, 3), config=None, pixel_sigma: float = 0.5
) -> list[dict]:
    """Random against D-optimal plans of the same size: predicted tool-tip bound (and median
    parameter bound) of each, per count and trajectory seed. Rows: count, seed, plan, bounds,
    the proxy's log det."""
    rows = []
    for n in counts:
        for seed in seeds:
            s = load_scenario(
                config,
                {
                    "noise": {"render": False, "pixel_sigma": pixel_sigma},
                    "trajectory": {"poses": int(n), "seed": int(seed)},
                },
            )
            inp = planning_inputs(s)
            q_rand = plan_postures(
                inp["robot"],
                inp["model_cam"],
                inp["T_left_right"],
                inp["intr"],
                inp["points_world"],
                n,
                seed=seed,
                min_visible=inp["min_visible"],
                normals_world=inp["normals_world"],
            )
            plan = plan_optimal(s)
            for kind, q in (("random", q_rand), ("optimal", plan.q)):
                b = predicted_bound(s, q)
                rows.append(
                    {
                        "poses": n,
                        "seed": seed,
                        "plan": kind,
                        "tool_tip_bound_mm": b["tool_tip_rms_mm"],
                        "median_param_bound": b["median_param_bound"],
                        "fx_bound_px": b["fx_px"],
                        "logdet_proxy": plan.logdet if kind == "optimal" else None,
                        "q_deg": np.degrees(q).tolist(),
                    }
                )
    return rows


def run_plan_comparison(
    out: str | Path,
    *,
    counts=(10, 20, 30),
    seeds=(1, 2, 3),
    draws: int = 12,
    mc_counts=(10, 30),
    jobs: int = 2,
    quiet: bool = False,
) -> dict:
    """Random against D-optimal postures: the predicted tool-tip bound for every count and
    trajectory seed (:func:`compare_plans`), and a Monte Carlo of ``draws`` noise draws for each
    plan kind at ``mc_counts`` (trajectory seed 1). Writes ``plans.csv``, ``plans.json``,
    ``plans.md`` and ``optimal_poses.png`` into ``out``; returns the JSON content."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = compare_plans(counts, seeds=seeds)
    mc: dict = {}
    for n in mc_counts:
        for kind in ("random", "optimal"):
            r = [x for x in rows if x["poses"] == n and x["seed"] == seeds[0] and x["plan"] == kind]
            if not r:
                continue
            if not quiet:
                print(f"Monte Carlo: {n} poses, {kind} plan, {draws} draws", file=sys.stderr)
            _, summ = run_montecarlo(
                draws,
                None,
                joints_deg=np.asarray(r[0]["q_deg"]),
                plan=kind,
                traj_seed=seeds[0],
                jobs=jobs,
                quiet=True,
            )
            mc[f"{n}_{kind}"] = {
                "poses": n,
                "plan": kind,
                "draws_ok": summ.get("ok"),
                "bound_mm": summ.get("tool_tip_bound_mm"),
                "joint_rms_mm": summ.get("joint", {}).get("tool_tip_rms_mm"),
                "joint_ratio": summ.get("joint", {}).get("tool_tip_ratio"),
                "joint_ratio_ci95": summ.get("joint", {}).get("tool_tip_ratio_ci95"),
                "two_stage_rms_mm": summ.get("two_stage", {}).get("tool_tip_rms_mm"),
            }
    res = {"bounds": [{k: v for k, v in r.items() if k != "q_deg"} for r in rows], "montecarlo": mc}
    _write_csv(res["bounds"], out / "plans.csv")
    (out / "plans.json").write_text(json.dumps(res, indent=2))
    (out / "plans.md").write_text(_plans_markdown(res))
    _plot_plans(res, out / "optimal_poses.png")
    return res


def _plans_markdown(res: dict) -> str:
    lines = [
        "# Random against D-optimal calibration postures",
        "",
        "Predicted Cramer-Rao bound of the validation tool-tip RMS (mm, after alignment) and the "
        "median parameter bound, per pose count and trajectory seed:",
        "",
        "| poses | seed | random tip bound | optimal tip bound | ratio | random median param "
        "| optimal median param |",
        "|---|---|---|---|---|---|---|",
    ]
    b = res["bounds"]
    for r in [x for x in b if x["plan"] == "random"]:
        o = [
            x
            for x in b
            if x["plan"] == "optimal" and x["poses"] == r["poses"] and x["seed"] == r["seed"]
        ][0]
        lines.append(
            f"| {r['poses']} | {r['seed']} | {r['tool_tip_bound_mm']:.4f} | "
            f"{o['tool_tip_bound_mm']:.4f} | {o['tool_tip_bound_mm'] / r['tool_tip_bound_mm']:.3f}"
            f" | {r['median_param_bound']:.4f} | {o['median_param_bound']:.4f} |"
        )
    if res["montecarlo"]:
        lines += [
            "",
            "Monte Carlo (trajectory seed 1, one truth, noise draws): achieved tool-tip RMS (mm)",
            "",
            "| poses | plan | draws | bound | one-step | one-step / bound (95 % CI) | two-stage |",
            "|---|---|---|---|---|---|---|",
        ]
        for v in res["montecarlo"].values():
            if v["bound_mm"] is None:
                continue
            lo, hi = v["joint_ratio_ci95"]
            lines.append(
                f"| {v['poses']} | {v['plan']} | {v['draws_ok']} | {v['bound_mm']:.4f} | "
                f"{v['joint_rms_mm']:.4f} | {v['joint_ratio']:.3f} ({lo:.2f} - {hi:.2f}) | "
                f"{v['two_stage_rms_mm']:.4f} |"
            )
    return "\n".join(lines) + "\n"


def _plot_plans(res: dict, path: Path) -> None:
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for kind, c in (("random", "tab:blue"), ("optimal", "tab:red")):
        rr = [x for x in res["bounds"] if x["plan"] == kind]
        ns = sorted({x["poses"] for x in rr})
        med = [np.median([x["tool_tip_bound_mm"] for x in rr if x["poses"] == n]) for n in ns]
        ax.plot(
            [x["poses"] for x in rr], [x["tool_tip_bound_mm"] for x in rr], ".", color=c, alpha=0.5
        )
        ax.plot(ns, med, "-", color=c, label=f"{kind} postures: bound (median over seeds)")
        mc = [v for v in res["montecarlo"].values() if v["plan"] == kind and v["joint_rms_mm"]]
        if mc:
            ax.plot(
                [v["poses"] for v in mc],
                [v["joint_rms_mm"] for v in mc],
                "s",
                color=c,
                mfc="none",
                ms=9,
                label=f"{kind}: one-step achieved (Monte Carlo RMS)",
            )
            ax.plot(
                [v["poses"] for v in mc],
                [v["two_stage_rms_mm"] for v in mc],
                "^",
                color=c,
                mfc="none",
                ms=8,
                label=f"{kind}: two-stage achieved",
            )
    ax.set_yscale("log")
    ax.set_xlabel("calibration postures")
    ax.set_ylabel("validation tool-tip RMS after alignment (mm)")
    ax.set_title("D-optimal against random postures (0.5 px, encoder read-back)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------------------- CLI
def _cmd(args: argparse.Namespace) -> int:
    if args.plans:
        res = run_plan_comparison(args.out, draws=args.draws, jobs=args.jobs, quiet=args.quiet)
        print(_plans_markdown(res))
        return 0
    _, s = run_montecarlo(
        args.draws,
        args.out,
        poses=args.poses,
        pixel_sigma=args.pixel_sigma,
        dither=not args.no_dither,
        jobs=args.jobs,
        quiet=args.quiet,
    )
    print(summary_markdown(s))
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal montecarlo --draws N --out DIR [--jobs N] [--poses P] [--pixel-sigma S]``."""
    sp = subparsers.add_parser(
        "montecarlo",
        help="Monte Carlo of both calibration methods against the Cramer-Rao bound",
        description="One truth (default scenario, analytic path), many noise draws: achieved "
        "tool-tip and parameter errors of the two-stage and the one-step method against the "
        "Cramer-Rao bound. Writes DIR/runs.csv, summary.md, summary.json, montecarlo.png. "
        "See docs/bounds.md.",
    )
    sp.add_argument("--draws", type=int, default=100, help="noise draws (default 100)")
    sp.add_argument("--out", required=True, help="output folder")
    sp.add_argument("--jobs", type=int, default=2, help="worker processes (1 = in-process)")
    sp.add_argument("--poses", type=int, default=30, help="calibration postures (default 30)")
    sp.add_argument("--pixel-sigma", type=float, default=0.5, help="corner noise, px")
    sp.add_argument(
        "--no-dither",
        action="store_true",
        help="keep the read-back rounding errors identical in every draw (part of the truth)",
    )
    sp.add_argument(
        "--plans",
        action="store_true",
        help="instead: random against D-optimal postures (bounds for 10/20/30 poses, 3 "
        "trajectory seeds; Monte Carlo of --draws draws at 10 and 30 poses)",
    )
    sp.add_argument("--quiet", action="store_true")
    sp.set_defaults(func=_cmd)
    return sp
