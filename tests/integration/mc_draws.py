"""The Monte Carlo draw of the acceptance tests, which read each draw's estimate and its bounds
only: :func:`selfcal.studies.montecarlo.run.draw_one` without the field calibration's fair
nominal (``fair_nominal = False``), whose fit was 15 % of a draw's CPU (lens.toml: 0.36 of
2.29 CPU s, time.process_time per stage) and which no acceptance claim reads. The estimate,
the bounds and every row field the tests read are the same; ``fair_nominal_tip_rms_mm`` is
NaN. A module of its own so that the spawned pool's workers import it by name."""

from __future__ import annotations

from selfcal.studies.montecarlo.run import draw_one


def draw_without_fair_nominal(settings: dict) -> dict:
    """``draw_one`` of ``settings`` with the fair nominal left out (module docstring)."""
    row = draw_one({**settings, "fair_nominal": False})
    assert row.get("fair_nominal") is False, (
        "the row must tell a skipped fair nominal from a failed one"
    )
    return row
