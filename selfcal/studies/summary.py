"""The outputs of a study (``selfcal.studies.study``): ``<name>.md`` and ``<name>.png`` from its
rows: the median and inter-quartile range over seeds of the validation tool-tip RMS per setting.

A study whose runs cover one setting only (the quick ``observation`` study) gets the table and no
plot: a curve of one point says nothing a table does not. Where the calibrated median is worse
than the nominal model's (the ``noise`` study at high noise), ``<name>.md`` says so and
:func:`worse_than_nominal` names the settings for the command to warn about.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from selfcal.plots.plotting import legend_outside, pyplot, save_figure
from selfcal.studies.defs import STUDIES, Study

__all__ = ["summarize", "study_figure", "worse_than_nominal", "plotted"]


def _stats(v: list[float]) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float)
    return float(np.median(a)), float(np.percentile(a, 25)), float(np.percentile(a, 75))


def summarize(name: str, rows: list[dict], out: str | Path) -> dict:
    """Write ``out/<name>.md`` and ``out/<name>.png`` from the study's rows; returns the table
    ``{series: {x: {n, failed, checks_failed, cal_median, cal_q25, cal_q75, nom_median,
    x_eff}}}`` (``checks_failed``: runs whose calibration failed its reliability checks)."""
    study = STUDIES[name]
    out = Path(out)
    table: dict = {}
    for r in rows:
        s = str(r.get(study.series)) if study.series else "all"
        x = r[study.x]
        cell = table.setdefault(s, {}).setdefault(
            x, {"cal": [], "nom": [], "eff": [], "failed": 0, "checks_failed": 0}
        )
        cell["checks_failed"] += int(r.get("checks") == "failed")
        if r["status"] == "ok" and r["cal_rms_mm"] is not None:
            cell["cal"].append(r["cal_rms_mm"])
            cell["nom"].append(r["nom_rms_mm"])
            cell["eff"].append(r["eff_noise_px"])
        else:
            cell["failed"] += 1
    res: dict = {}
    for s, xs in table.items():
        for x, c in sorted(xs.items()):
            if c["cal"]:
                m, q1, q3 = _stats(c["cal"])
                res.setdefault(s, {})[x] = {
                    "n": len(c["cal"]),
                    "failed": c["failed"],
                    "checks_failed": c["checks_failed"],
                    "cal_median": m,
                    "cal_q25": q1,
                    "cal_q75": q3,
                    "nom_median": float(np.median(c["nom"])),
                    "eff_noise_median": float(np.median(c["eff"])),
                }
            else:
                res.setdefault(s, {})[x] = {
                    "n": 0,
                    "failed": c["failed"],
                    "checks_failed": c["checks_failed"],
                }
    _write_md(study, res, out / f"{name}.md")
    png = out / f"{name}.png"
    if plotted(res):
        fig = study_figure(study, res, rows)
        save_figure(fig, png, dpi=110)
        pyplot().close(fig)
    else:
        png.unlink(missing_ok=True)  # a plot of an earlier, wider run of the study is stale
    return res


def plotted(res: dict) -> bool:
    """Whether a study's table ``res`` (of :func:`summarize`) is drawn: it has results at two
    or more settings."""
    return len({x for xs in res.values() for x, c in xs.items() if c["n"]}) >= 2


def worse_than_nominal(study: Study, res: dict) -> list[str]:
    """One sentence per setting where the calibrated median is above the nominal model's."""
    return [
        f"{_series_label(study, s)} at {study.x} = {x}: calibrated median {c['cal_median']:.3f} "
        f"mm is worse than the nominal model's {c['nom_median']:.3f} mm"
        for s, xs in res.items()
        for x, c in xs.items()
        if c["n"] and c["cal_median"] > c["nom_median"]
    ]


def _series_label(study: Study, s: str) -> str:
    if study.series == "render":
        return "rendered images" if s == "True" else "analytic, same effective noise"
    return "calibrated"


def _write_md(study: Study, res: dict, path: Path) -> None:
    lines = [
        f"# Study `{study.name}`",
        "",
        "Validation tool-tip RMS error (mm, 20 held-out postures, after rigid alignment): median "
        "and inter-quartile range over seeds; the nominal model's median is over the same "
        "(successful) runs. Failed runs are listed in runs.csv with their reason. Checks "
        "failed: finished runs whose calibration failed its reliability checks (marked FAILED "
        "by `selfcal calibrate`; runs.csv columns checks and failed_checks), counted in the "
        "statistics all the same.",
        "",
        f"| series | {study.x} | runs ok | failed | calibrated median | q25 | q75 | nominal median "
        "| effective corner noise (px) | checks failed |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s, xs in res.items():
        for x, c in xs.items():
            if c["n"]:
                lines.append(
                    f"| {_series_label(study, s)} | {x} | {c['n']} | {c['failed']} | "
                    f"{c['cal_median']:.3f} | {c['cal_q25']:.3f} | {c['cal_q75']:.3f} | "
                    f"{c['nom_median']:.3f} | {c['eff_noise_median']:.3f} | "
                    f"{c.get('checks_failed', 0)} |"
                )
            else:
                lines.append(
                    f"| {_series_label(study, s)} | {x} | 0 | {c['failed']} | | | | | | "
                    f"{c.get('checks_failed', 0)} |"
                )
    total = sum(c.get("checks_failed", 0) for xs in res.values() for c in xs.values())
    runs = sum(c["n"] + c["failed"] for xs in res.values() for c in xs.values())
    lines += ["", f"Reliability checks: {total} of {runs} run(s) failed them."]
    worse = worse_than_nominal(study, res)
    if worse:
        lines += ["", "**Warning**: calibration made the model worse here:", ""]
        lines += [f"- {w}" for w in worse]
    if not plotted(res):
        lines += ["", "One setting only: a table, no plot."]
    path.write_text("\n".join(lines) + "\n")


def study_figure(study: Study, res: dict, rows: list[dict]) -> Any:
    """The figure of ``<name>.png``: medians, inter-quartile ranges and runs against the swept
    setting, and the nominal model's median; the legend beside the axes."""
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    colors = {"all": "tab:red", "True": "tab:blue", "False": "tab:orange"}
    offsets = {"True": -0.1, "False": 0.1} if study.series else {"all": 0.0}
    nom_x, nom_y = [], []
    for s, xs in res.items():
        xv = sorted(x for x, c in xs.items() if c["n"])
        if not xv:
            continue
        med = [xs[x]["cal_median"] for x in xv]
        lo = [xs[x]["cal_q25"] for x in xv]
        hi = [xs[x]["cal_q75"] for x in xv]
        xp = np.asarray(xv, dtype=float)
        if study.series:
            xp = xp + offsets.get(s, 0.0) * (np.ptp(xp) if np.ptp(xp) > 0 else 1.0)
        c = colors.get(s, "tab:red")
        ax.plot(xp, med, "o-", color=c, label=f"{_series_label(study, s)} (median)")
        ax.fill_between(xp, lo, hi, color=c, alpha=0.2, label="inter-quartile range")
        pts = [
            (r[study.x], r["cal_rms_mm"])
            for r in rows
            if r["status"] == "ok" and (not study.series or str(r[study.series]) == s)
        ]
        if pts:
            px, py = np.asarray(pts, dtype=float).T
            if study.series:
                px = px + offsets.get(s, 0.0) * (np.ptp(xp) if np.ptp(xp) > 0 else 1.0)
            ax.plot(px, py, ".", color=c, alpha=0.35, ms=4)
        for x, xpk in zip(xv, xp):
            if xs[x]["failed"]:
                ax.annotate(
                    f"{xs[x]['failed']} failed",
                    (xpk, xs[x]["cal_median"]),
                    textcoords="offset points",
                    xytext=(0, -14),
                    ha="center",
                    fontsize=7,
                    color=c,
                )
        nom_x += list(xv)
        nom_y += [xs[x]["nom_median"] for x in xv]
    if nom_x:
        order = np.argsort(nom_x)
        ux, idx = np.unique(np.asarray(nom_x)[order], return_index=True)
        ax.plot(ux, np.asarray(nom_y)[order][idx], "k--", lw=1, label="nominal model (median)")
    ax.set_yscale("log")
    if study.log_x:
        ax.set_xscale("log")
    ax.set_xlabel(study.xlabel)
    ax.set_ylabel("validation tool-tip RMS error (mm)")
    ax.set_title(f"study '{study.name}': error after calibration vs {study.x}")
    ax.grid(alpha=0.3, which="both")
    if ax.get_legend_handles_labels()[0]:  # nothing to label when every run failed
        legend_outside(ax)
    return fig
