"""The rendered field benchmark's corner noise (selfcal.benchmarks.plan.field_noise): kept in
``corner-noise.json`` with the cell, the seed and the code that measured it, and measured again
when any differs, so a table is never closed with another code's noise (review of session 24:
the file recorded no code and was reused whenever cell and seed matched)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from selfcal.benchmarks import corner_noise
from selfcal.benchmarks.plan import field_noise
from selfcal.studies.montecarlo import run


@pytest.fixture
def measure(tmp_path, monkeypatch):
    """measured_noise with the rendering and detection replaced: each measurement returns the
    next of 0.1, 0.2, ... px; returns (call(code) -> the noise, the measurements made)."""
    made: list[float] = []

    def corners(_root):
        made.append(0.1 * (len(made) + 1))
        return SimpleNamespace(to_json=lambda: {"count": 10, "sigma_px": made[-1], "outliers": 0})

    monkeypatch.setattr(run, "acquire_draw", lambda settings, out: None)
    monkeypatch.setattr(corner_noise, "field_corner_noise", corners)

    def call(code: str | None, cell: str = "ur5e rendered 0.5 px postures abc") -> dict:
        monkeypatch.setattr(field_noise, "code_version", lambda: code)
        return field_noise.measured_noise(tmp_path, tmp_path / "s.toml", [[0.0] * 6], cell, 0.5)

    return call, made


def test_the_noise_is_kept_with_the_code_that_measured_it(measure, tmp_path):
    call, made = measure
    first = call("abc1234")
    assert first["code"] == "abc1234" and first["sigma_px"] == pytest.approx(0.1)
    assert json.loads((tmp_path / "corner-noise.json").read_text()) == first
    assert call("abc1234") == first and len(made) == 1  # the same code, cell and seed: read


@pytest.mark.parametrize("code", ["def5678", "abc1234+changes", None])
def test_another_codes_noise_is_measured_again(measure, tmp_path, code):
    call, made = measure
    call("abc1234")
    again = call(code)
    assert len(made) == 2 and again["sigma_px"] == pytest.approx(0.2) and again["code"] == code
    assert json.loads((tmp_path / "corner-noise.json").read_text())["code"] == code


def test_an_older_file_without_a_code_is_measured_again(measure, tmp_path):
    call, made = measure
    cell = "ur5e rendered 0.5 px postures abc"
    old = {"cell": cell, "seed": field_noise.NOISE_SEED, "count": 9, "sigma_px": 0.5, "outliers": 0}
    (tmp_path / "corner-noise.json").write_text(json.dumps(old))
    assert call("abc1234", cell)["sigma_px"] == pytest.approx(0.1) and len(made) == 1
