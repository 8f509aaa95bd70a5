"""What ``selfcal plan`` says of a camera plan: its closing lines, plan.json's sections on the
selection's forecast and the reference without calibrating the kinematics, and the criterion
in words (issue #30)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the CLI's parser loads no numerical module (tests/unit/test_cli_imports.py)
    from selfcal.calibration.board.plan.reference import NominalReference

__all__ = [
    "criterion",
    "forecast_note",
    "measured_gain",
    "plan_lines",
    "plan_sections",
    "reference_words",
]


def reference_words(ref: NominalReference, predicted_m: float, rival_m: float | None = None) -> str:
    """The reference and the verdict on a calibration predicted at ``predicted_m`` (m, with the
    parameters the selection is forecast to keep): the error without calibrating the kinematics
    and whether the prediction beats it clearly; ``rival_m`` (m) the prediction with the smaller
    set the selection may keep instead (a caveat, not the verdict's decider), None without
    one."""
    from selfcal.calibration.board.plan.reference import CLEAR_MARGIN

    mm = ref.best_m * 1000
    head = (f"without calibrating the kinematics {mm:.3f} mm ({ref.what}; "
            + (f"{ref.placement} fitted to the pixels; the chain as drawn is no reference: "
               f"{ref.drawn_why}" if ref.drawn_why else
               f"the fair nominal, {ref.placement} fitted to the pixels: "
               f"{ref.fair_m * 1000:.3f} mm" if ref.what == "the chain as drawn" else
               f"the chain as drawn: {ref.drawn_m * 1000:.3f} mm") + ")")  # fmt: skip
    ratio = predicted_m / ref.best_m
    if ref.beaten_by(predicted_m):
        words = f"{head}: the calibration is predicted at {ratio:.2f} times it"
    else:
        words = (f"{head}: NOT predicted to beat it by a clear margin ({ratio:.2f} times it, a "
                 f"clear gain is at most {CLEAR_MARGIN:g}): the calibration may be no better "
                 f"than {ref.what}")  # fmt: skip
    if rival_m is None:
        return words
    rival = rival_m / ref.best_m
    if ref.beaten_by(predicted_m) and not ref.beaten_by(rival_m):
        return (f"{words}; but if the selection keeps the smaller set, {rival:.2f} times it: "
                "no clear gain")  # fmt: skip
    return f"{words} ({rival:.2f} times it if the selection keeps the smaller set)"


def plan_lines(plan) -> str:
    """The closing lines of a camera plan
    (:class:`selfcal.calibration.board.plan.planner.RecordingPlan`)."""
    import numpy as np

    n, dof = len(plan.q), plan.q.shape[1]
    sel = plan.selected
    kept = (f"{sel.selected_m * 1000:.3f} mm RMS with the {sel.kept(dof)} kinematic parameters "
            "beyond the placement the calibration's selection is forecast to keep")  # fmt: skip
    if sel.rival_m is not None:  # each figure beside its own set, not a range
        kept = (f"{sel.selected_m * 1000:.3f} mm RMS ({sel.kept(dof)} parameters) or "
                f"{sel.rival_m * 1000:.3f} mm ({sel.rival_kept(dof)}): the kinematic parameters "
                "beyond the placement the calibration's selection is forecast to keep, or the "
                "smaller set it may keep instead")  # fmt: skip
    first = f"plan of {n} postures: predicted tool-point error {kept}"
    if sel.kept(dof) == plan.kept_all and sel.rival_m is None:
        first += (f", all the postures identify (a random plan of {n} with all it identifies: "
                  f"{plan.random_m * 1000:.3f} mm)")  # fmt: skip
    else:
        first += (f" (with all {plan.kept_all} the postures identify {plan.predicted_m * 1000:.3f}"
                  f" mm; a random plan of {n}: ")  # fmt: skip
        if plan.random_selected_m is None:
            first += f"{plan.random_m * 1000:.3f} mm)"
        else:  # the plan's figure beside the random plan's on the same basis, then with all
            first += (f"{plan.random_selected_m * 1000:.3f} mm with what its selection is "
                      f"forecast to keep, {plan.random_m * 1000:.3f} mm with all)")  # fmt: skip
    if plan.chosen_by != "greedy":
        same = " (the random plan)" if plan.is_the_random_plan else ""
        first += (f"; the pool's {plan.chosen_by}{same}: the greedy choice (its criterion estimates "
                  f"every parameter) predicted {plan.greedy_m * 1000:.3f} mm with those its "
                  "selection is forecast to keep")  # fmt: skip
    first += f"; joint path {np.degrees(plan.path_rad):.0f} deg"
    second = reference_words(plan.reference, sel.selected_m, sel.rival_m)
    if not sel.beats(plan.reference):
        if plan.to_beat is not None:
            k, got = plan.to_beat
            second += (f"; record more postures: a plan of {k} (--count {k}) is predicted "
                       f"{got * 1000:.3f} mm")  # fmt: skip
        else:
            second += (f"; no plan of up to {plan.searched} postures from these candidates is "
                       "predicted to beat it (plan other board or camera poses to compare)")  # fmt: skip
    return f"{first}\n{second}"


def plan_sections(plan) -> dict:
    """plan.json's sections of a camera plan beyond the prediction with every identified
    parameter: the selection's forecast, its prediction, the reference and the verdict."""
    sel, dof = plan.selected, plan.q.shape[1]
    fc = sel.forecast
    return {
        "chosen_by": plan.chosen_by,
        "greedy_selection_tool_rms_mm": round(plan.greedy_m * 1000, 4),
        "random_selection_tool_rms_mm": (
            None if plan.random_selected_m is None else round(plan.random_selected_m * 1000, 4)
        ),
        "identified_kinematic_parameters": plan.kept_all,
        "selection": {
            "tool_rms_mm": round(sel.selected_m * 1000, 4),
            "kinematic_parameters": sel.kept(dof),
            "rival_tool_rms_mm": None if sel.rival_m is None else round(sel.rival_m * 1000, 4),
            "rival_kinematic_parameters": sel.rival_kept(dof),
            "chosen": fc.label,
            "folds": fc.folds,
            **({"folds_counted": list(fc.counted)} if fc.counted and not all(fc.counted) else {}),
            "candidates": [
                {"label": lab, "fold_rms_px": [round(v, 4) for v in rms]}
                for lab, rms in zip(fc.labels, fc.fold_rms_px)
            ],
            "note": (
                "predicted with the kinematic parameters (beyond the placement) the "
                "selection's cross-validation is forecast to keep, the others held at the "
                "drawing; rival: the next smaller candidate, when its expected CV error is "
                "near enough that the one-standard-error rule may keep it; "
                "predicted_tool_rms_mm keeps every one the postures identify"
            ),
        },
        "nominal": plan.reference.to_json(),
        "beats_nominal": sel.beats(plan.reference),
        "rival_beats_nominal": sel.rival_beats(plan.reference),
        "verdict": reference_words(plan.reference, sel.selected_m, sel.rival_m),
        "verdict_note": (
            "beats_nominal and more_postures judge the prediction with the parameters the "
            "selection is forecast to keep (selection.tool_rms_mm); rival_beats_nominal the "
            "smaller set it may keep instead (null: no rival)"
        ),
        "more_postures": (
            None
            if plan.to_beat is None
            else {"count": plan.to_beat[0], "tool_rms_mm": round(plan.to_beat[1] * 1000, 4)}
        ),
    }


def criterion(workspace: int, pixel_sigma: float, js, args: argparse.Namespace) -> str:
    """plan.json's criterion in words."""
    joints = ("joints read exactly" if js is None else "joint read-back noise of the robot "
              "file's encoder table (its motors' counts rounded), each frame's corrections "
              "estimated")  # fmt: skip
    return (
        "board route Cramer-Rao bound with the parameters the selection's rank test keeps, "
        f"the others held at the drawing, deviating uniformly within +-{args.deviation_mm:g} mm "
        f"and +-{args.deviation_deg:g} deg: RMS of the flange centre over {workspace} random "
        f"workspace postures after the best rigid alignment, corner noise {pixel_sigma:g} px, "
        + joints
    )


def measured_gain(selection: dict | None, held_out: tuple[float, float] | None,
                  held_out_file: str = "evaluation.json") -> dict | None:  # fmt: skip
    """What a dataset's calibration measured against its fair nominal on its own images, when
    it measured a gain: ``cv_px`` (calibrated, fair nominal) from its ``selection`` (its
    calibration.json's block: the chosen candidate's and the nominal's cross-validation, the
    folds' geometric mean, px) when the chosen candidate is not the nominal and predicts better,
    and ``held_out_px`` = ``held_out`` (calibrated, nominal px: the held-out check of this
    calibration, ``held_out_file``) when it shows a gain (the rule of
    :func:`selfcal.calibration.board.evaluate.no_gain`); ``words`` says them. None when neither
    measured a gain."""
    from selfcal.calibration.board.evaluate import no_gain

    out: dict = {}
    sel = selection or {}
    cands = {c["label"]: c for c in sel.get("candidates", [])}
    if cands and sel.get("chosen") in cands:
        first, chosen = sel["candidates"][0], cands[sel["chosen"]]
        c, n = chosen.get("cv_px"), first.get("cv_px")
        if chosen is not first and c is not None and n is not None and not no_gain(c, n):
            out["cv_px"], out["chosen"] = (c, n), chosen["label"]
    if held_out is not None and not no_gain(*held_out):
        out["held_out_px"] = held_out
    if not out:
        return None
    parts = []
    if "cv_px" in out:
        c, n = out["cv_px"]
        parts.append(f"cross-validated {c:.3f} px against the fair nominal's {n:.3f} px "
                     f"({out['chosen']}; geometric means over the folds)")  # fmt: skip
    if "held_out_px" in out:
        c, n = out["held_out_px"]
        parts.append(f"held out {c:.3f} px against the fair nominal's {n:.3f} px "
                     f"({held_out_file})")  # fmt: skip
    out["words"] = ", ".join(parts)
    return out


def forecast_note(measured: dict, deviation_words: str) -> str:
    """What a forecast that the dataset's calibration is no gain is, beside the gain that
    calibration measured (:func:`measured_gain`'s ``measured``): they answer different
    questions, the tool point's error over the workspace expected of arms drawn within the
    deviation ``deviation_words``, and this arm's pixels in images the calibration did not fit
    (no measurement of its tool point)."""
    return (f"; that is a forecast, not a measurement: the tool point's error over the region "
            f"expected of arms whose every kinematic parameter deviates alike within "
            f"{deviation_words}; this arm's calibration measured a gain in the pixels of images "
            f"it did not fit ({measured['words']}), a different question: nothing measured its "
            "tool point")  # fmt: skip
