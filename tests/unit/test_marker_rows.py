"""The column-wise reader of detections.csv's marker corners (selfcal/io/marker_rows.py) gives
the row-by-row reader's dictionary, in its order, or leaves the file to it."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_dataset_fuzz import INFO, JOINTS

from selfcal.io import dataset as dataset_module
from selfcal.io.dataset import Dataset
from selfcal.io.dataset_info import write_dataset_info
from selfcal.io.marker_rows import marker_corners

HEADER = "index,camera,marker_id,corner,u_px,v_px"


def rows_of(markers) -> list[str]:
    """Data lines of ``markers`` [(frame, camera, marker id)] (corners 0-3 each), shuffled."""
    rng = np.random.default_rng(5)
    lines = [f"{i},{c},{m},{k},{rng.uniform(0, 640):.6f},{rng.uniform(0, 480):.6f}"
             for i, c, m in markers for k in range(4)]  # fmt: skip
    return [lines[j] for j in rng.permutation(len(lines))]


def dataset(root: Path, lines: list[str]) -> Dataset:
    """A dataset of frames 0-3 (the fuzz test's) whose detections.csv holds ``lines``."""
    root.mkdir(parents=True, exist_ok=True)
    write_dataset_info(root / "dataset.json", INFO)
    (root / "joints.csv").write_text(JOINTS)
    (root / "detections.csv").write_text("\n".join([HEADER, *lines]) + "\n")
    return Dataset.open(root)


def row_by_row(root: Path, lines: list[str]) -> dict:
    """The dataset reader's row-by-row result (the column-wise reader switched off)."""
    ds = dataset(root, lines)
    saved = dataset_module.marker_corners
    dataset_module.marker_corners = lambda lines, keep: None
    try:
        return ds.read_detections()
    finally:
        dataset_module.marker_corners = saved


def same(a: dict, b: dict) -> bool:
    """Equal dictionaries of corners, keys in the same order and of the same types."""
    if list(a) != list(b) or any(type(x) is not type(y) for k in zip(a, b) for x, y in zip(*k)):
        return False
    return all(list(a[k]) == list(b[k]) and all(np.array_equal(a[k][m], b[k][m], equal_nan=True)
                                                 for m in a[k]) for k in a)  # fmt: skip


def test_column_reader_gives_the_row_readers_dictionary_in_its_order(tmp_path):
    markers = [(i, c, m) for i in (3, 0, 7, 2) for c in ("right", "left") for m in (31, 3, 12)]
    lines = rows_of(markers)
    fast = marker_corners(lines, np.arange(4))  # frame 7's rows are read and checked, not kept
    assert fast is not None and same(fast, row_by_row(tmp_path, lines))
    assert (7, "left") not in fast and len(fast) == 6 and all(len(v) == 3 for v in fast.values())


@pytest.mark.parametrize(
    "change",
    [
        lambda ls: ls[:1] + ['0,"left",3,0,1.0,2.0'] + ls[1:],  # csv quoting
        lambda ls: ls + [ls[0]],  # a corner twice: the last row wins
        lambda ls: [x for x in ls if not x.startswith("0,left,3,2,")],  # a corner missing
        lambda ls: ls[:2] + [""] + ls[2:],  # a blank line
        lambda ls: ls + ["0,left,9,4,1.0,2.0"],  # corner 4
        lambda ls: ls + ["0,left,9.0,0,1.0,2.0"],  # not an integer
        lambda ls: [x + ",extra" for x in ls],  # seven columns
        lambda ls: ls + ["0,left,9,0,nan,2.0"],  # NaN
    ],
)
def test_anything_else_is_left_to_the_row_reader(tmp_path, change):
    lines = change(sorted(rows_of([(0, "left", 3), (0, "right", 3)])))
    assert marker_corners(lines, np.arange(4)) is None
    # the dataset's reader then answers (or names the row) as the row reader does
    try:
        got = dataset(tmp_path / "a", lines).read_detections()
    except dataset_module.DatasetError as exc:
        with pytest.raises(dataset_module.DatasetError) as raised:
            row_by_row(tmp_path / "b", lines)
        assert str(raised.value).replace("/b/", "/a/") == str(exc)
    else:
        assert same(got, row_by_row(tmp_path / "b", lines))


VALID = st.sampled_from(["0", "1", "3", "-1", "7", "2.5", "1e3", " 3", "+2", "0.125"])
NUMBER = st.one_of(VALID, VALID, VALID, VALID, st.sampled_from(["nan", "", "x", "3 ", "1_0"]))
MARKER = st.tuples(st.sampled_from(["0", "1", "3", "7", " 2", "+1"]),
                   st.sampled_from(["left", "right", "", " left"]),
                   st.sampled_from(["3", "-4", "12", "9"]))  # fmt: skip


@settings(max_examples=100, deadline=None)
@given(st.lists(MARKER, max_size=6, unique=True), st.lists(st.lists(NUMBER, min_size=2,
       max_size=2), min_size=4, max_size=4), st.lists(st.lists(NUMBER, min_size=6, max_size=6),
       max_size=1),
       st.randoms())  # fmt: skip
def test_when_it_reads_a_file_it_reads_it_as_the_row_reader(tmp_path_factory, markers, uv,
                                                            extra, rnd):  # fmt: skip
    lines = [",".join([i, c, m, str(k), *uv[k]]) for i, c, m in markers for k in range(4)]
    lines += [",".join(r) for r in extra]
    rnd.shuffle(lines)
    fast = marker_corners(lines, np.arange(4))
    if fast is None:
        return
    assert same(fast, row_by_row(tmp_path_factory.mktemp("d"), lines))
    assert all(len(next(csv.reader([x]))) == 6 for x in lines)
