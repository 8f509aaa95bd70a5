"""report.md gives a board calibration's cross-validated reprojection twice: the accuracy
section's RMS over every held-out corner together and the parameter selection's table of
geometric means over the folds. On the repository's Nachi set they read 1.768 px and 1.390 px
for the same candidate; each must say which aggregate it is (new user's trip, session 26)."""

from __future__ import annotations

from selfcal.pipeline.board_accuracy import cross_validation_line
from selfcal.pipeline.report_fit import selection_markdown

CV = {
    "configurations": 5,
    "folds": 5,
    "calibrated": {"label": "+ joint offsets", "corners": 1760, "reprojection_rms_px": 1.7684,
                   "at_board_rms_mm": 0.4098},
    "nominal": {"label": "nominal (placement + camera)", "corners": 1760,
                "reprojection_rms_px": 1.9598, "at_board_rms_mm": 0.4504},
}  # fmt: skip


def test_the_cross_validation_line_says_it_pools_every_held_out_corner():
    line = cross_validation_line(CV)
    assert line is not None
    assert "RMS over the 1760 held-out corners of all folds together" in line
    assert "geometric mean" in line  # points at the table's other aggregate
    assert "calibrated 1.768 px (0.410 mm at the board), fair nominal 1.960 px" in line


def test_an_older_block_without_corner_counts_still_reads():
    old = {**CV, "calibrated": {k: v for k, v in CV["calibrated"].items() if k != "corners"}}
    line = cross_validation_line(old)
    assert line is not None and "RMS over the held-out corners of all folds together" in line


def test_the_line_names_how_many_folds_count_in_new_and_older_blocks():
    """``accuracy.cross_validation`` says how many folds count as ``folds_counting`` (an int;
    ``folds_counted`` in session 29's blocks, the same name as the selection's flag per fold)."""
    for key in ("folds_counting", "folds_counted"):
        line = cross_validation_line({**CV, key: 4})
        assert line is not None and "held-out corners of the 4 folds that count" in line, line


def test_the_selection_table_says_its_cross_validated_column_is_a_geometric_mean():
    sel = {
        "identified": ["offset_j2"],
        "chosen": "+ joint offsets",
        "rule": "one-standard-error rule",
        "candidates": [{"label": "+ joint offsets", "n_parameters": 16, "fit_rms_px": 0.6,
                        "cv_px": 1.39, "fold_rms_px": [0.95, 3.153, 1.63, 1.002, 1.062]}],
    }  # fmt: skip
    header = selection_markdown(sel)[2]
    assert "cross-validated (px, geometric mean over the folds)" in header
    assert "per fold (px, RMS)" in header
