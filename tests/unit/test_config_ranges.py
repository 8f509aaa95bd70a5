"""Every numeric scenario key has a documented valid range (issue #15): values out of it, NaN and
infinity are refused naming file, key, value and range."""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path

import pytest

from selfcal.config.scenario import (
    RANGES,
    ConfigError,
    Scenario,
    _fmt,
    load_scenario,
    ranges_markdown,
)

DOC = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"


def _numeric_keys(cls: type, prefix: str = "") -> list[str]:
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp, key = hints[f.name], f"{prefix}{f.name}"
        if dataclasses.is_dataclass(tp):
            out += _numeric_keys(tp, key + ".")
        elif tp in (int, float) or typing.get_args(tp) in ((int,), (float,)):
            out.append(key)
    return out


def test_every_numeric_key_has_a_range_and_the_doc_shows_the_table():
    keys = _numeric_keys(Scenario)
    missing = [k for k in keys if k not in RANGES]
    assert not missing, missing
    assert {"camera.distortion", "perturbation.table"} <= set(RANGES)
    assert ranges_markdown() in DOC.read_text()
    # the defaults and the shipped scenarios are inside every range
    for p in [None, *sorted(DOC.parents[1].glob("scenarios/*.toml"))]:
        load_scenario(p)


@pytest.mark.parametrize(
    "section, key, value, shown",
    [
        ("noise", "image_sigma", "1e6", "1000000"),
        ("noise", "pixel_sigma", "1e4", "10000"),
        ("camera", "fx", "inf", "inf"),
        ("camera", "fx", "nan", "nan"),
        ("target", "scale_length_mm", "1e-9", "1e-09"),
        ("camera", "mu", "-1", "-1"),
        ("trajectory", "poses", "3", "3"),
        ("camera", "resolution", "[640, 1000000]", "1000000"),
        ("camera", "distortion", "{ k1 = nan }", "nan"),
    ],
)
def test_out_of_range_values_name_file_key_value_and_range(tmp_path, section, key, value, shown):
    p = tmp_path / "s.toml"
    extra = 'model = "opencv"\n' if key == "distortion" else ""
    p.write_text(f"[{section}]\n{extra}{key} = {value}\n")
    with pytest.raises(ConfigError) as err:
        load_scenario(p)
    msg = str(err.value)
    r = RANGES[f"{section}.{key}"]
    for word in (str(p), f"{section}.{key}", f"= {shown}", f"{_fmt(r.lo)} .. {_fmt(r.hi)}"):
        assert word in msg, (word, msg)


def test_a_marker_field_scenario_needs_its_own_minimum(tmp_path):
    """trajectory.poses takes the board calibration's 4 (tests/unit/test_fold_counting.py); the
    marker field's self-calibration still needs 6, said with the key before anything runs."""
    p = tmp_path / "s.toml"
    p.write_text("[trajectory]\nposes = 5\n")
    with pytest.raises(ConfigError, match=r"trajectory.poses = 5: the marker field's "
                       r"self-calibration needs 6 postures or more"):  # fmt: skip
        load_scenario(p)
    board = DOC.parents[1] / "models" / "targets" / "charuco.toml"
    p.write_text(f'[trajectory]\nposes = 4\n[target]\nboard = "{board}"\n')
    assert load_scenario(p).trajectory.poses == 4
