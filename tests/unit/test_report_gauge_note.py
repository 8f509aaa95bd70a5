"""The own-data report's parameter table when the selection identified joint offsets: the
offsets have no rows (calibration.json writes the chain with the nominal's offsets) and held
parameters carry them. On the photoneo set (tests/data/real, `selfcal report` of its calibration)
report.md listed offset_j2..offset_j5 as identified, showed none of them, and showed `lx2` as
held (nominal -0.0000 mm, estimate 5.0943 mm) with no word on why."""

from __future__ import annotations

from selfcal.pipeline.report_fit import gauge_note


def _row(name, unit, nominal, estimate, held):
    return {"name": name, "unit": unit, "nominal": nominal, "estimate": estimate,
            "std": None if held else 0.01, "held": "rank" if held else None}  # fmt: skip


ROWS = [
    _row("lx0", "mm", -690.7319, -691.8811, False),
    _row("lx2", "mm", -0.0, 5.0943, True),
    _row("beta3", "deg", -0.0, 0.2395, True),
    _row("ly4", "mm", 810.0, 810.0, True),
]


def test_identified_offsets_without_rows_and_the_held_rows_they_move_are_named():
    note = gauge_note(ROWS, ["lx0", "offset_j2", "offset_j3"])
    assert note is not None
    assert "offset_j2, offset_j3 have no rows" in note
    assert "lx2 +5.0943 mm" in note and "beta3 +0.2395 deg" in note
    assert "ly4" not in note and "lx0" not in note  # unmoved held, and estimated, rows
    # identified parameters outside the minimal set the table shows (the photoneo set's gamma0,
    # lz0) are named apart, not as offsets
    note = gauge_note(ROWS, ["gamma0", "offset_j2"])
    assert note is not None and "offset_j2 have no rows" in note
    assert "gamma0 (identified) have no rows: the table shows the MCPC's minimal" in note


def test_no_note_when_every_identified_parameter_has_a_row():
    assert gauge_note(ROWS, ["lx0"]) is None
    assert gauge_note(ROWS, []) is None
