"""calibrate's line names the kinematic parameters identified beyond the placement and those
the postures cannot identify: a new user's 2-joint pan-tilt said only "2 kinematic
parameter(s) beyond the placement identified" (calibration.json's selection held the names)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.parameter_pool import NAMES_SHOWN, identified_words
from selfcal.kinematics.mcpc import nominal_mcpc, param_names
from selfcal.pipeline.board_run import _nominal_text
from selfcal.robot.definition import load_robot

RANK = "rank: not identifiable from these postures (a combination of the others)"
PANTILT = nominal_mcpc(load_robot(str(Path(__file__).resolve().parents[1] / "data/pantilt2.urdf")))
PLACEMENT = list(param_names(placement_indices(PANTILT.n)))  # board pose and hand-eye


def test_a_pan_tilts_line_names_what_it_identified_and_what_it_cannot():
    sel = {
        "identified": [*PLACEMENT, "lx1", "alpha1"],
        "chosen": "+ all identifiable",
        "candidates": [
            {"label": "nominal (placement + camera)", "parameters": PLACEMENT, "cv_px": 0.742},
            {
                "label": "+ all identifiable",
                "parameters": [*PLACEMENT, "lx1", "alpha1"],
                "cv_px": 0.735,
            },
        ],  # fmt: skip
        "held": {
            "offset_j1": RANK,
            "offset_j2": RANK,
            "beta1": RANK,
            "ly1": RANK,
            "ly2": "cross-validation: + all identifiable predicts worse",
        },  # fmt: skip
    }
    res = SimpleNamespace(nominal_rms_px=0.730, selection=sel, cv_verdict=lambda: None,
                          model=PANTILT)  # fmt: skip
    assert _nominal_text(res) == (
        " (fair nominal 0.730 px); 2 kinematic parameter(s) beyond the placement identified "
        "(lx1, alpha1; 4 not identifiable from these postures: offset_j1, offset_j2, beta1, "
        "ly1), cross-validated 0.735 px against the nominal's 0.742 px (geometric mean over "
        "the folds)"
    )


def test_the_line_says_which_folds_its_cross_validation_counts():
    """The selection's errors are over the folds that count (a fold leaving out more than half
    of the frames does not, folds.counted_folds); the line said "over the folds" (review of
    session 28, finding 9)."""
    sel = {
        "chosen": "+ lx1",
        "candidates": [
            {"label": "nominal (placement + camera)", "parameters": PLACEMENT, "cv_px": 0.742},
            {"label": "+ lx1", "parameters": [*PLACEMENT, "lx1"], "cv_px": 0.735},
        ],
        "folds_counted": [True, True, False, True],
    }
    res = SimpleNamespace(nominal_rms_px=0.730, selection=sel, cv_verdict=lambda: None,
                          model=PANTILT)  # fmt: skip
    assert _nominal_text(res).endswith(
        "cross-validated 0.735 px against the nominal's 0.742 px (geometric mean over the 3 of "
        "4 folds that count)"
    )
    sel["folds_counted"] = [True] * 4  # every fold counts: as before
    assert _nominal_text(res).endswith("(geometric mean over the folds)")


def test_long_lists_are_counted():
    many = [f"lx{k}" for k in range(NAMES_SHOWN + 3)]
    words = identified_words(many, {})
    assert (
        words.endswith(f"lx{NAMES_SHOWN - 1} and 3 more)") and words.count(",") == NAMES_SHOWN - 1
    )
    assert identified_words([], {"lx1": "cross-validation: predicts worse"}) == ""
    assert identified_words([], {"beta1": "conditioning: adds 1e-9"}) == (
        " (1 not identifiable from these postures: beta1)")  # fmt: skip
