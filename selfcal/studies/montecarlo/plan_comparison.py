"""``selfcal montecarlo --plans``: random against D-optimal calibration postures.

The Cramer-Rao bounds of a plan before acquisition (:func:`predicted_bound`), random against
D-optimal plans of the same size (:func:`compare_plans`), and a Monte Carlo of each plan kind
(:func:`run_plan_comparison`). The collision check is :mod:`selfcal.sim.collision`'s, the optimal plan of a
scenario :func:`selfcal.acquisition.backends.plan_optimal`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.acquisition.backends import plan_dataset, plan_optimal, planning_inputs
from selfcal.acquisition.simulator_setup import SimSetup, sim_setup
from selfcal.calibration.field.bounds import FisherSetup, cramer_rao
from selfcal.calibration.field.bounds_setup import predicted_setup
from selfcal.calibration.field.joint_refine import encoder_sigma
from selfcal.camera import Rig
from selfcal.config.scenario import load_scenario
from selfcal.io.atomic import write_text_atomic
from selfcal.kinematics.mcpc import minimal_indices, param_is_angle
from selfcal.kinematics.trajectory import plan_postures
from selfcal.plots.plotting import legend_outside, pyplot, save_figure
from selfcal.studies.montecarlo.run import run_montecarlo, write_csv
from selfcal.transforms import inv_pose

__all__ = [
    "sim_fisher_setup",
    "predicted_bound",
    "compare_plans",
    "run_plan_comparison",
    "plans_markdown",
]


def sim_fisher_setup(
    setup: SimSetup, q: np.ndarray, scale_length_m: float, **kwargs: Any
) -> FisherSetup:
    """:func:`selfcal.calibration.field.bounds_setup.predicted_setup` of postures ``q`` (m, n) rad with the
    simulator's actual robot, stereo rig and marker field of ``setup`` and the scale markers
    ``scale_length_m`` (m) apart; ``kwargs`` go to ``predicted_setup`` (noise, reference)."""
    fld = setup.marker_field()
    return predicted_setup(
        setup.actual,
        q,
        Rig.stereo(setup.intrinsics, setup.T_left_right, setup.intrinsics_right),
        fld.ids,
        fld.corners_world(),
        fld.T_world_marker[:, :3, 2],
        (int(fld.scale_ids[0]), int(fld.scale_ids[1])),
        scale_length_m,
        **kwargs,
    )


def predicted_bound(s, q: np.ndarray) -> dict:
    """The Cramer-Rao bounds (mm, deg) of a plan ``q`` (m, n) rad before acquisition, from the
    simulator's actual robot and marker field (:func:`selfcal.calibration.field.bounds_setup.predicted_setup`): the
    validation tool-tip RMS and the median parameter bound."""
    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    st = sim_fisher_setup(
        setup,
        q,
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
                inp["rig"],
                inp["points_world"],
                n,
                seed=seed,
                min_visible=inp["min_visible"],
                normals_world=inp["normals_world"],
                collision_ok=inp["collision_ok"],
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
    cluster: str | None = None,
) -> dict:
    """Random against D-optimal postures: the predicted tool-tip bound for every count and
    trajectory seed (:func:`compare_plans`), and a Monte Carlo of ``draws`` noise draws for each
    plan kind at ``mc_counts`` (trajectory, perturbation and first noise seed ``seeds[0]``). Writes ``plans.csv``, ``plans.json``,
    ``plans.md`` and ``optimal_poses.png`` into ``out``; returns the JSON content. ``cluster``: a
    Dask scheduler address for the Monte Carlo draws (docs/cluster.md)."""
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
                perturb_seed=seeds[0],
                first_seed=seeds[0],
                jobs=jobs,
                quiet=True,
                cluster=cluster,
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
    bounds = [{k: v for k, v in r.items() if k != "q_deg"} for r in rows]
    res = {"bounds": bounds, "montecarlo": mc}
    write_csv(bounds, out / "plans.csv")
    write_text_atomic(out / "plans.json", json.dumps(res, indent=2))
    write_text_atomic(out / "plans.md", plans_markdown(res))
    _plot_plans(res, out / "optimal_poses.png")
    return res


def plans_markdown(res: dict) -> str:
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


_ACHIEVED = (
    ("joint_rms_mm", "s", 9, "one-step achieved (Monte Carlo RMS)"),
    ("two_stage_rms_mm", "^", 8, "two-stage achieved"),
)
"""The Monte Carlo results :func:`_plot_plans` marks: key, marker, size, label."""


def _plot_plans(res: dict, path: Path) -> None:
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(10, 4.5), constrained_layout=True)
    for kind, c in (("random", "tab:blue"), ("optimal", "tab:red")):
        rr = [x for x in res["bounds"] if x["plan"] == kind]
        ns = sorted({x["poses"] for x in rr})
        med = [np.median([x["tool_tip_bound_mm"] for x in rr if x["poses"] == n]) for n in ns]
        ax.plot(
            [x["poses"] for x in rr], [x["tool_tip_bound_mm"] for x in rr], ".", color=c, alpha=0.5
        )
        ax.plot(ns, med, "-", color=c, label=f"{kind} postures: bound (median over seeds)")
        mc = [v for v in res["montecarlo"].values() if v["plan"] == kind and v["joint_rms_mm"]]
        for key, marker, size, what in _ACHIEVED if mc else ():
            ax.plot(
                [v["poses"] for v in mc],
                [v[key] for v in mc],
                marker,
                color=c,
                mfc="none",
                ms=size,
                label=f"{kind}: {what}",
            )
    ax.set_yscale("log")
    ax.set_xlabel("calibration postures")
    ax.set_ylabel("validation tool-tip RMS after alignment (mm)")
    ax.set_title("D-optimal against random postures (0.5 px, encoder read-back)")
    ax.grid(alpha=0.3, which="both")
    legend_outside(ax, fontsize=7)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
