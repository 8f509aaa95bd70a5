"""Issue #14's done-when on the rendered path: the noise-free default scenario and the rendered
Monte Carlo against the Cramer-Rao bound (selfcal/studies/montecarlo/render.py, docs/accuracy.md)."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.pipeline.run import dithered
from selfcal.robot.definition import load_robot
from selfcal.studies.montecarlo.render import run_draws, summarise


def test_dithered_postures_move_within_half_a_motor_count():
    robot = load_robot("er4u-paper")
    planned = np.tile(np.degrees(robot.home), (50, 1))
    a, b = dithered(planned, robot, 1), dithered(planned, robot, 2)
    half = 0.5 * np.degrees(robot.encoder.count_step)  # deg
    assert np.all(np.abs(a - planned) <= half) and np.all(np.abs(b - planned) <= half)
    assert not np.allclose(a, b) and np.array_equal(a, dithered(planned, robot, 1))
    # a uniform fraction of a motor count in every joint
    np.testing.assert_allclose(np.std(a - planned, axis=0), 2 * half / np.sqrt(12), rtol=0.3)


@pytest.mark.slow
@pytest.mark.render
def test_noise_free_rendered_default_scenario(tmp_path):
    """No image noise, the encoders' rounding as acquired: tool tip 0.0092 mm RMS, largest
    parameter |z| 1.06 (beta3) (measured; issue #14's target <= 0.02 mm and no parameter beyond
    3 sigma; before the second line pass and the side screening 0.0219 mm and |z| 2.90)."""
    (row,) = run_draws(1, tmp_path, image_sigma=0.0, dither=False)
    assert row["rms_mm"] <= 0.02, row
    assert row["max_abs_z"] < 3.0, row
    assert row["sigma_source"] == "detector"


@pytest.mark.slow
@pytest.mark.render
def test_rendered_monte_carlo_at_the_bound(tmp_path):
    """Eight rendered draws (image noise and dithered postures, seeds 1-8; the full 20-draw run
    is in docs/accuracy.md): the tool tip's RMS over the draws within 1.15x the bound (issue
    #14). Measured: 0.80x over these 8 (0.0183 against 0.0227 mm; 0.66x with the float noise
    draws before session 27's integer noise), 0.74x over 20 (docs/accuracy.md, float noise)."""
    rows = run_draws(8, tmp_path)
    s = summarise(rows)
    assert s["ratio"] <= 1.15, s
    assert all(r["sigma_source"] == "detector" for r in rows)
