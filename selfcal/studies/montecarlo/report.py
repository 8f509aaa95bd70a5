"""The Monte Carlo's outputs: ``summary.md`` (:func:`summary_markdown`) and ``montecarlo.png``
(:func:`plot`) from the rows and the summary of :mod:`selfcal.studies.montecarlo.stats`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.plots.plotting import legend_outside, pyplot, save_figure
from selfcal.studies.montecarlo.stats import METHODS

__all__ = ["summary_markdown", "plot"]


def summary_markdown(s: dict) -> str:
    if not s.get("ok"):
        return (
            f"# Monte Carlo\n\nno successful draw ({s.get('failed', 0)} failed); reliability "
            f"checks: {s.get('checks_failed', 0)} of {s.get('draws', 0)} draws failed them\n"
        )
    st = s.get("settings", {})
    lines = [
        "# Monte Carlo: achieved error against the Cramer-Rao bound",
        "",
        f"{'Default scenario' if not st.get('config') else 'Scenario ' + str(st['config'])}, "
        f"analytic path, one truth (perturbation seed {st.get('perturb_seed')}, "
        f"trajectory seed {st.get('traj_seed')}, plan {st.get('plan')}, {st.get('poses')} poses), "
        f"{s['ok']} noise draws ({s['failed']} failed), corner noise {st.get('pixel_sigma')} px, "
        f"read-back dithered: {st.get('dither')}.",
        "",
        (
            f"Reliability checks (of the final, joint calibration; runs.csv columns checks and "
            f"failed_checks): {s.get('checks_failed', 0)} of {s['draws']} draws failed them."
            if s.get("checks_run", 1)
            else "The board route runs no reliability checks; two-stage: the camera stage and "
            "the identification on its camera poses; parameters in the board frame."
        ),
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
    if s.get("camera_ratios"):
        lines += [
            "",
            "Camera parameters of the joint method, error RMS / bound: "
            + ", ".join(f"{n} {v:.3f}" for n, v in s["camera_ratios"].items())
            + ".",
        ]
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], s: dict, path: Path) -> None:
    plt = pyplot()

    ok = [r for r in rows if r.get("status") == "ok"]
    if not ok:
        return
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(14, 4.2), constrained_layout=True)
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
    legend_outside(a1)
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
    a2.set_title("parameters (reference-camera frame; of a board: the board frame)")
    legend_outside(a2)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
