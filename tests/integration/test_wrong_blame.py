"""Bad input named as bad input (#33): each case below exited 1 (a bug's code) with a Python
exception's text, or 2/3 blaming something else; now exit 2 naming the file and the key."""

from __future__ import annotations

import json
import shutil

import pytest
from analytic_dataset import acquire_analytic, run


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """8 postures on the analytic path (detections, no rendering)."""
    return acquire_analytic(tmp_path_factory.mktemp("blame") / "ds", 8, 3)


def _edited(src, dst, edit):
    shutil.copytree(src, dst)
    doc = json.loads((dst / "dataset.json").read_text())
    edit(doc)
    (dst / "dataset.json").write_text(json.dumps(doc))
    return dst


@pytest.mark.parametrize(
    ("value", "shown"), [(float("nan"), "nan"), (-200.0, "-200.0"), (1e308, "1e+308")]
)
def test_a_bad_scale_length_names_file_and_key(capsys, dataset, tmp_path, value, shown):
    """Before: NaN and -200 exit 3 naming neither file nor key, 1e308 exit 1 (LinAlgError)."""
    ds = _edited(dataset, tmp_path / "ds", lambda d: d["target"].update(scale_length_mm=value))
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert f"{ds / 'dataset.json'}: key 'target.scale_length_mm' must be a length > 0" in err
    assert f"got {shown}" in err


def test_an_unknown_dictionary_names_file_and_key(capsys, dataset, tmp_path):
    """Before: exit 1, ValueError."""
    ds = _edited(dataset, tmp_path / "ds", lambda d: d["target"].update(dictionary="DICT_FOO"))
    code, _, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and "key 'target.dictionary' must be a cv2.aruco dictionary" in err
    assert "'DICT_FOO'" in err and str(ds / "dataset.json") in err


def test_a_robot_model_naming_no_robot_says_so(capsys, dataset, tmp_path):
    """Before: exit 2 about an encoder-table mismatch."""
    ds = _edited(dataset, tmp_path / "ds", lambda d: d.update(robot_model="no-such-arm"))
    code, _, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and str(ds / "dataset.json") in err and "robot_model" in err
    assert "no-such-arm" in err and "encoder" not in err


@pytest.mark.parametrize("name", ["dataset.json", "joints.csv"])
def test_non_utf8_bytes_name_the_file(capsys, dataset, tmp_path, name):
    """Before: exit 1, UnicodeDecodeError."""
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    text = (ds / name).read_bytes()
    (ds / name).write_bytes(text[:30] + b"\xff\xfe\xfa" + text[30:])
    code, _, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and f"{ds / name}: not UTF-8 text" in err
