"""Totality of the dataset reader (issue #15): any joints.csv, detections.csv or dataset.json text
ends in a dataset (finite joints, complete or with its missing frames listed) or a DatasetError
naming the file, never another exception. Inputs: arbitrary text, and rows of random cells (NaN,
inf, 5000 digits, empty, too few or too many, cut off without a newline)."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
from conftest import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_readers_fuzz import ANY_TEXT, CELL

from selfcal.io.dataset import Dataset, DatasetError
from selfcal.io.dataset_info import DatasetInfo, write_dataset_info

INFO = DatasetInfo(
    robot_model="er4u-paper",
    resolution=(64, 48),
    dictionary="DICT_4X4_50",
    scale_ids=(48, 49),
    scale_length_m=0.2,
    observation="detections",
    planned_joints_deg=np.arange(20.0).reshape(4, 5),
    validation_joints_deg=np.zeros((0,)),
)
JOINTS = "index,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg\n" + "".join(
    f"{i},{','.join(str(5.0 * i + j) for j in range(5))}\n" for i in range(4)
)
DETECTIONS = "index,camera,marker_id,corner,u_px,v_px\n" + "".join(
    f"{i},{c},3,{k},{10 + k}.5,{20 + k}.25\n" for i in range(4) for c in ("left", "right")
    for k in range(4)
)  # fmt: skip


@st.composite
def csv_text(draw, header: str, first: st.SearchStrategy):
    rows = draw(
        st.lists(
            st.tuples(first, st.lists(CELL, min_size=0, max_size=7)).map(
                lambda r: ",".join([r[0], *r[1]])
            ),
            max_size=6,
        )
    )
    text = "\n".join([header, *rows]) + "\n"
    return text[: -draw(st.integers(0, 3))] if draw(st.booleans()) else text


def _dataset(files: dict[str, str]) -> Path:
    root = Path(tempfile.mkdtemp())
    write_dataset_info(root / "dataset.json", INFO)
    (root / "joints.csv").write_text(JOINTS)
    (root / "detections.csv").write_text(DETECTIONS)
    for name, text in files.items():
        (root / name).write_text(text, encoding="utf-8", errors="surrogateescape")
    return root


def _open_all(root: Path) -> None:
    """Open, check and read the dataset: values or a DatasetError naming a file of it."""
    try:
        ds = Dataset.open(root)
        assert np.isfinite(ds.joints_deg).all() and ds.joints_deg.shape[1] == 5
        assert set(ds.missing) | set(ds.indices.tolist()) >= set(range(4))
        ds.check_complete(allow_missing=True)
        ds.check_complete()
        ds.read_detections()
    except DatasetError as exc:
        assert str(root) in str(exc), str(exc)


# 60 draws per reader, fewer than the other readers' 150: each draw writes a dataset folder
FUZZ = settings(
    max_examples=examples(60), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
INDEX = st.one_of(st.integers(-2, 6).map(str), CELL)


@FUZZ
@given(st.one_of(csv_text("index,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg", INDEX), ANY_TEXT))
def test_joints_csv_reader_is_total(text):
    _open_all(_dataset({"joints.csv": text}))


@FUZZ
@given(st.one_of(csv_text("index,camera,marker_id,corner,u_px,v_px", INDEX), ANY_TEXT))
def test_detections_csv_reader_is_total(text):
    _open_all(_dataset({"detections.csv": text}))


JSON_VALUES = st.one_of(
    st.sampled_from([None, True, 0, -1, 1e308, "x", "", [], [[]], {}, [1, 2], [[1, 2, 3, 4]]]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
)


@FUZZ
@given(st.sampled_from(sorted(INFO.to_json())), JSON_VALUES)
def test_dataset_json_reader_is_total(key, value):
    doc = INFO.to_json()
    doc[key] = value
    _open_all(_dataset({"dataset.json": json.dumps(doc)}))


@FUZZ
@given(st.sampled_from(["dataset.json", "joints.csv", "detections.csv"]), st.data())
def test_dataset_files_take_any_bytes(name, data):
    """Bytes that are not UTF-8 anywhere in a dataset file (before: UnicodeDecodeError, exit 1)
    end in a DatasetError naming the file, or a dataset (#33)."""
    from test_readers_fuzz import damaged_bytes

    root = _dataset({})
    raw = data.draw(st.one_of(st.binary(max_size=120), damaged_bytes((root / name).read_bytes())))
    (root / name).write_bytes(raw)
    _open_all(root)
