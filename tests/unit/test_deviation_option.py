"""`selfcal calibrate --deviation-mm/--deviation-deg` (selfcal/cli/own_data.py): the board
route's prior on the arm's deviation from its drawing, refused elsewhere and when negative."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.calibration.board.deviation import Deviation
from selfcal.cli.own_data import deviation_option
from selfcal.console.common import CliError


def test_the_deviation_options_give_the_board_routes_prior():
    assert deviation_option(Path("ds"), "board", None, None) is None  # the default's
    d = deviation_option(Path("ds"), "board", 0.2, None)
    assert d == Deviation(0.2e-3, Deviation().rotation_rad)
    d = deviation_option(Path("ds"), "board", None, 0.05)
    assert d.translation_m == Deviation().translation_m
    assert d.rotation_rad == pytest.approx(np.radians(0.05))


@pytest.mark.parametrize(("route", "mm", "deg", "match"), [
    ("field", 0.2, None, "apply to a board dataset"),
    ("handeye", None, 0.1, "apply to a board dataset"),
    ("board", -1.0, None, "must be finite and >= 0"),
    ("board", None, float("nan"), "must be finite and >= 0"),
])  # fmt: skip
def test_the_deviation_options_are_refused_where_they_mean_nothing(route, mm, deg, match):
    with pytest.raises(CliError, match=match):
        deviation_option(Path("ds"), route, mm, deg)
