"""``selfcal report DIR`` on real data (no ``truth.json``): what the data itself says.

The fit (reprojection RMS, inliers, frames used), a held-out reprojection -- from
``DIR/evaluation.json`` when ``selfcal evaluate`` wrote one with a second dataset, else the
leave-some-poses-out check (:func:`selfcal.calibration.field.holdout.leave_poses_out`: every 5th
frame in the order of their joints predicted by a calibration of the others) -- the parameters with their standard deviations against the fair
nominal (the nominal chain with hand-eye, camera, rig and marker corners fitted to the same
pixels: ``calibration.json`` ``nominal``, :mod:`selfcal.calibration.field.nominal_fit`),
and the identifiability (rank, condition number, held parameters and why). Never the simulator.
A board calibration (``selfcal import`` of your own data) gets the same report from its own
numbers: fit, held-out check, the camera's sigmas, the parameters against the nominal reference
and the ones held (:func:`board_fit_report`). Output: ``DIR/report.json`` and ``DIR/report.md``
(``"kind": "fit"``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.calibration.board.evaluate import evaluation_of, no_gain, worse
from selfcal.errors import EXIT_INTERNAL, SelfCalError
from selfcal.io.atomic import write_text_atomic
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.calibration import CalibrationResult
from selfcal.io.dataset import Dataset
from selfcal.io.jsonfile import write_report
from selfcal.kinematics.accuracy import parameter_table
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.pipeline.report_cameras import rig_camera_markdown, rig_camera_rows
from selfcal.robot.definition import load_robot

__all__ = ["fit_report", "board_fit_report", "fit_markdown", "write_fit_report", "HOLDOUT_EVERY"]

HOLDOUT_EVERY = 5
"""The leave-some-poses-out check holds out every 5th frame (6 of the default 30)."""


def _held_out(root: Path, method: str, every: int, chosen: str | None = None) -> dict:
    """The held-out check of ``report.json``: ``DIR/evaluation.json`` when there, else the
    leave-poses-out check; ``chosen``: the candidate the dataset's board calibration chose
    (its ``selection.chosen``), beside which the check's own calibration's choice is named when
    they differ (``selection_note``: the check then judges another model than the file's)."""
    # as export: an evaluation of another calibration judges that one (warned, not used)
    ev_path, ev = evaluation_of(root, stacklevel=3)
    if ev is not None:
        return {"source": "selfcal evaluate", "file": str(ev_path), "dataset": ev.dataset,
                "images": len(ev.images), "features": sum(i["features"] for i in ev.images),
                "reprojection_rms_px": dict(ev.rms)}  # fmt: skip
    # the held-out calibrations (both routes' calibrators) load for a report without truth only
    from selfcal.calibration.field.holdout import leave_poses_out

    try:
        h = leave_poses_out(root, every=every, method=method)
    except SelfCalError as exc:
        if exc.exit_code == EXIT_INTERNAL:  # a bug, not a finding about the data
            raise
        return {"source": "leave-poses-out", "error": str(exc)}
    ev = h.evaluation
    differs = {}
    if chosen is not None and h.chosen is not None and h.chosen != chosen:
        differs["selection_note"] = (
            f"that calibration chose {h.chosen} where calibration.json chose {chosen}: these "
            "held-out figures judge its choice, not calibration.json's (selfcal evaluate with a "
            "second dataset, --out DIR/evaluation.json, judges the file itself)"
        )
    return {
        "source": "leave-poses-out",
        **({} if h.chosen is None else {"chosen": h.chosen}),
        **differs,
        "every": every,
        "held_out_frames": list(h.held_out),
        "images": len(ev.images),
        "features": sum(i["features"] for i in ev.images),
        "reprojection_rms_px": dict(ev.rms),
        "note": (
            f"every {every}th frame (in the order of their joint readings, so not chosen by the "
            f"rows' order) held out, the other {len(h.fitted)} calibrated afresh with the "
            f"same method ({method}); the held-out images predicted from their joint readings "
            "alone"
        ),
    }


def fit_report(root: str | Path, cal: CalibrationResult, *, every: int = HOLDOUT_EVERY) -> dict:
    """The report of the field calibration ``cal`` of the dataset in ``root`` without truth
    (module docstring); lengths mm, angles deg, image quantities px."""
    root = Path(root)
    est = cal.model
    nominal = cal.nominal_model
    if nominal is None:  # a file from before the fair nominal was stored (or its fit failed)
        robot = load_robot(Dataset.open(root).robot_source)
        nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    nominal = express_in_frame(nominal, np.eye(4), like=est)
    std_si = {p.name: np.nan if p.std is None else p.std * p.to_si for p in cal.parameters}
    params = parameter_table(est, std_si, None, nominal)
    held = {**cal.identification.held, **({} if cal.joint is None else cal.joint.held)}
    for row in params:
        row["held"] = held.get(row["name"])
    i = cal.intrinsics
    ident = cal.identification
    identifiability = {
        "method": cal.method,
        "two_stage": {"rank": ident.rank, "n_params": ident.n_params,
                      "condition_number": ident.condition_number,
                      "observability_o1": ident.observability_o1,
                      "observability_o3": ident.observability_o3},
        "held": held,
    }  # fmt: skip
    if cal.joint is not None:
        identifiability["joint"] = {"rank": cal.joint.rank, "n_unknowns": cal.joint.n_unknowns,
                                    "gauge_held": list(cal.joint.gauge_held)}  # fmt: skip
    return {
        "kind": "fit",
        "note": "no truth.json (real data): the fit, a held-out check, sigmas and identifiability",
        "fit": {
            "method": cal.method,
            "frames": cal.dataset.frames,
            "frames_used": cal.dataset.frames_used,
            "reprojection_rms_px": cal.reprojection_rms_px,
            "inliers": cal.observations.inliers,
            "outliers": cal.observations.outliers,
            "corner_noise_px": None if cal.joint is None else cal.joint.sigma_px,
        },
        "held_out": _held_out(root, cal.method, every),
        "intrinsics": {
            "fx": {"estimate": i.fx, "std": i.fx_std},
            "mu": {"estimate": i.mu, "std": i.mu_std},
            **{n: {"estimate": v, "std": i.std.get(n)} for n, v in i.distortion.items()},
        },
        **({"cameras": cams} if (cams := rig_camera_rows(cal, None)) else {}),
        "scale_factor": cal.scale.k,
        "parameters": params,
        "parameters_note": (
            "nominal: the fair nominal, the nominal chain with hand-eye, camera and marker "
            "corners fitted to the pixels (calibration.json nominal), in the estimate's frame; "
            "std: 1 sigma from the fit"
            if cal.nominal is not None
            else "nominal: the robot file's chain in its base frame (calibration.json holds no "
            "fair nominal: re-run `selfcal calibrate`), so the base parameters do not compare; "
            "std: 1 sigma from the fit"
        ),
        "identifiability": identifiability,
        "warnings": list(cal.warnings),
        "failures": list(cal.failures),
    }


def board_fit_report(
    root: str | Path, cal: BoardCalibrationResult, *, every: int = HOLDOUT_EVERY
) -> dict:
    """The report of the board calibration ``cal`` of the dataset in ``root`` (no truth): as
    :func:`fit_report`; the kinematics' sigmas are their Cramer-Rao bounds at the estimate
    (``calibration.json`` ``bounds``), the camera's its fit's, and the parameters it held."""
    root = Path(root)
    reasons = {} if cal.selection is None else cal.selection.get("held", {})
    held = {n: reasons.get(n, "held: not identifiable from this data") for n in cal.held}
    params = parameter_table(cal.model, {}, None, cal.nominal_model)
    # the kinematics' sigmas: the Cramer-Rao bound at the estimate with the fit's own noise
    # (calibration.json bounds), what an efficient estimator's standard deviation is
    bound = {b.name: b.bound for b in cal.bounds.parameters} if cal.bounds is not None else {}
    for row in params:
        row["held"] = held.get(row["name"])
        if row["held"] is None and bound.get(row["name"]) is not None:
            row["std"] = bound[row["name"]]
    cam, std = cal.cameras[0], cal.camera_std[0]
    values = dict(zip(cam.names, cam.values().tolist(), strict=True))
    return {
        "kind": "fit",
        "note": "no truth.json (real data): the fit, a held-out check, sigmas and identifiability",
        "fit": {
            "method": "board",
            "frames": cal.frames,
            "frames_used": cal.frames_used,
            "reprojection_rms_px": cal.reprojection_rms_px,
        },
        "held_out": _held_out(root, "board", every, (cal.selection or {}).get("chosen")),
        "intrinsics": {n: {"estimate": values[n], "std": std.get(n)} for n in cam.free},
        "parameters": params,
        "parameters_note": (
            "nominal: the fair nominal, the nominal chain with hand-eye, board pose and camera "
            "fitted to the pixels (calibration.json nominal_mcpc), in the estimate's frame; 1 sigma: the Cramer-Rao bound at the "
            "estimate with the fit's noise (calibration.json bounds), none when it has no bounds"
        ),
        "identifiability": {"method": "board", "held": held,
                            **({} if cal.selection is None else {"selection": cal.selection})},
        **({} if (verdict := cal.cv_verdict()) is None else {"verdict": f"no gain: {verdict}"}),
        "warnings": list(cal.warnings),
    }  # fmt: skip


def fit_markdown(r: dict, figures: list[str]) -> str:
    """``report.md`` of a report without truth."""
    f, h = r["fit"], r["held_out"]
    counts = (f" over {f['inliers']} inlier corners ({f['outliers']} outliers)"
              if "inliers" in f else "")  # fmt: skip
    lines = [
        "# Calibration report (real data: no truth)",
        "",
        f"Fit ({f['method']}): {f['frames_used']}/{f['frames']} frames, reprojection RMS "
        f"{f['reprojection_rms_px']:.3f} px{counts}.",
        "",
        "## Held-out reprojection",
        "",
    ]
    if "error" in h:
        lines.append(f"Not available: {h['error']}")
    else:
        rms = h["reprojection_rms_px"]
        src = (f"`selfcal evaluate` on {h['dataset']}" if h["source"] == "selfcal evaluate"
               else h["note"])  # fmt: skip
        note = (
            f" {h['selection_note'][0].upper()}{h['selection_note'][1:]}."
            if "selection_note" in h
            else ""
        )
        lines += [
            f"{src}: {h['features']} features in {h['images']} images.{note}",
            "",
            "| model | held-out reprojection RMS (px) |",
            "|---|---|",
            f"| nominal reference | {rms['nominal']:.3f} |",
            f"| calibrated | {rms['calibrated']:.3f} |",
        ]
    if "verdict" in r:
        lines += ["", f"**{r['verdict']}**"]
    if r.get("accuracy", {}).get("route") == "field":  # a field calibration's
        from selfcal.pipeline.field_accuracy import field_accuracy_markdown

        lines += field_accuracy_markdown(r["accuracy"])
    elif "accuracy" in r:  # a board calibration's (its modules load for it alone)
        from selfcal.pipeline.board_accuracy import accuracy_markdown

        lines += accuracy_markdown(r["accuracy"])
    idf = r["identifiability"]
    lines += ["", "## Identifiability", ""]
    if "two_stage" in idf:
        ts = idf["two_stage"]
        lines.append(
            f"Two-stage identification rank {ts['rank']}/{ts['n_params']}, condition number "
            f"{ts['condition_number']:.3g}, observability index O1 {ts['observability_o1']:.3g}."
        )
    elif not idf["held"]:
        lines.append("Every parameter was identified (none held).")
    if "joint" in idf:
        j = idf["joint"]
        lines.append(
            f"One-step refinement: rank {j['rank']}/{j['n_unknowns']} unknowns; gauge held: "
            f"{', '.join(j['gauge_held']) or 'none'}."
        )
    if "selection" in idf:
        lines += selection_markdown(idf["selection"])
    if idf["held"]:
        lines += ["", "Held parameters:", ""]
        lines += [f"- {k}: {v}" for k, v in idf["held"].items()]
    cam = ", ".join(
        f"{n} = {v['estimate']:.6g}" + ("" if v["std"] is None else f" ± {v['std']:.2g}")
        for n, v in r["intrinsics"].items()
    )
    lines += ["", "## Camera", "", f"{cam} (± 1 sigma).", "",
              *rig_camera_markdown(r.get("cameras", {})), "## Parameters", "",
              parameter_markdown(r["parameters"], truth=False)]  # fmt: skip
    if gauge := gauge_note(r["parameters"], idf.get("selection", {}).get("identified", [])):
        lines += ["", gauge]
    lines += figure_links(figures)
    if r["warnings"]:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in r["warnings"]]
    return "\n".join(lines) + "\n"


def selection_markdown(sel: dict) -> list[str]:
    """The parameter selection of a board calibration (calibration.json ``selection``): what
    was identified, the rule and every candidate's cross-validated errors: the geometric mean
    over the folds that count (``cv_px``, what the selection compares) and each fold's RMS, a
    fold that does not count (``folds_counted``) marked."""
    out = [
        f"Identified: {', '.join(sel['identified'])} (chosen: {sel['chosen']}; {sel['rule']}).",
        "",
        "| candidate | parameters | fit (px) | cross-validated (px, geometric mean over the folds) "
        "| per fold (px, RMS) |",
        "|---|---|---|---|---|",
    ]
    counted = sel.get("folds_counted") or []
    for c in sel["candidates"]:
        fit = "-" if c["fit_rms_px"] is None else f"{c['fit_rms_px']:.3f}"
        cv = "-" if c["cv_px"] is None else f"{c['cv_px']:.3f}"
        folds = ", ".join(("-" if v is None else f"{v:.3f}")
                          + ("" if k >= len(counted) or counted[k] else " (not counted)")
                          for k, v in enumerate(c["fold_rms_px"]))  # fmt: skip
        out.append(f"| {c['label']} | {c['n_parameters']} | {fit} | {cv} | {folds} |")
    return out


def gauge_note(rows: list[dict], identified: list[str]) -> str | None:
    """Why identified parameters have no row and held ones moved, or None: ``calibration.json``
    writes the chain in the MCPC gauge with the fair nominal's joint offsets
    (:func:`selfcal.calibration.board.nominal_fit.standard_gauge`), which writes an identified
    joint offset into the link parameters (held ones too: the fit held them, the gauge moves
    them); identified parameters outside the minimal set the table shows are named apart.
    ``rows``: the parameter table (:func:`parameter_markdown`'s, mm / deg); ``identified``: the
    selection's names."""
    names = {p["name"] for p in rows}
    offsets = [n for n in identified if n not in names and n.startswith("offset_j")]
    others = [n for n in identified if n not in names and not n.startswith("offset_j")]
    moved = [p for p in rows if p.get("held") and abs(p["estimate"] - p["nominal"]) >= 5e-5]
    if not offsets and not others:
        return None
    text = ""
    if offsets:
        text = (f"The identified {', '.join(offsets)} have no rows: calibration.json writes the "
                "chain with the nominal's joint offsets (the MCPC gauge), which writes an offset "
                "into the link parameters")  # fmt: skip
        if moved:
            shown = ", ".join(f"{p['name']} {p['estimate'] - p['nominal']:+.4f} {p['unit']}"
                              for p in moved)  # fmt: skip
            text += (f"; so held parameters differ from the nominal ({shown}): not estimated, "
                     "they carry the offsets")  # fmt: skip
        text += ". "
    if others:
        text += (f"{', '.join(others)} (identified) have no rows: the table shows the MCPC's "
                 "minimal parameters, which do not include them.")  # fmt: skip
    return text.strip()


def parameter_markdown(rows: list[dict], *, truth: bool) -> str:
    """The parameter table (mm / deg): nominal, estimate, 1 sigma, and with ``truth`` the truth
    and the estimate's error."""
    head = "| parameter | unit | nominal | estimate | 1 sigma |"
    rule = "|---|---|---|---|---|"
    if truth:
        head += " truth | estimate - truth |"
        rule += "---|---|"
    out = [head, rule]
    for p in rows:
        sd = "held" if p.get("held") else ("-" if p["std"] is None else f"{p['std']:.4f}")
        line = (f"| {p['name']} | {p['unit']} | {p['nominal']:.4f} | {p['estimate']:.4f} | "
                f"{sd} |")  # fmt: skip
        if truth:
            line += f" {p['truth']:.4f} | {p['estimate'] - p['truth']:+.4f} |"
        out.append(line)
    return "\n".join(out)


def bound_markdown(bound_mm: float | None, achieved_mm: float, method: str = "") -> str:
    """The report's sentence on the Cramer-Rao bound of the calibrated tool-tip RMS (mm) and,
    when the achieved error of this one data set is below it, why that is no contradiction."""
    if bound_mm is None:
        return "No Cramér-Rao bound was computed for this calibration."
    text = (f"Cramér-Rao bound of the calibrated tool-tip RMS for this data: {bound_mm:.3f} mm "
            f"({method}see calibration.json `bounds`).")  # fmt: skip
    if achieved_mm < bound_mm:
        text += (
            f" The achieved {achieved_mm:.3f} mm is below it: the bound is the RMS expected over "
            "noise draws, and one draw can beat it (`selfcal montecarlo` shows the spread over "
            "draws)."
        )
    return text


def figure_links(figures: list[str]) -> list[str]:
    """Markdown image links of ``figures`` (paths relative to the report)."""
    if not figures:
        return []
    return ["", "## Figures", ""] + [f"![{Path(p).stem}]({p})" for p in figures]


def write_fit_report(root: Path, report: dict, drawn: list[Path], *, quiet: bool) -> dict:
    """Write ``root/report.json`` and ``report.md`` of a fit ``report`` (:func:`fit_report`,
    :func:`board_fit_report`) with the figures ``drawn``: its verdict "no gain" when the held-out
    reprojection of the calibrated model is not below the nominal reference's, a failure when it
    is worse; returns the report."""
    report["figures"] = [str(p.relative_to(root)) for p in drawn]
    failures = list(report.get("failures", []))
    rms = report["held_out"].get("reprojection_rms_px")
    if rms is not None and "verdict" not in report and no_gain(rms["calibrated"], rms["nominal"]):
        report["verdict"] = (
            f"no gain: the held-out reprojection of the calibrated model "
            f"({rms['calibrated']:.3f} px) is not below the nominal reference's "
            f"({rms['nominal']:.3f} px)"
        )
    if rms is not None and worse(rms["calibrated"], rms["nominal"]):
        failures.append(
            f"the held-out reprojection of the calibrated model ({rms['calibrated']:.3f} px) is "
            f"worse than the nominal reference's ({rms['nominal']:.3f} px): do not use it"
        )
    report["status"], report["failures"] = ("failed" if failures else "ok"), failures
    write_report(root / "report.json", report)
    md = fit_markdown(report, report["figures"])
    write_text_atomic(root / "report.md", md)
    return report
