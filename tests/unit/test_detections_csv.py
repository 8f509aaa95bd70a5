"""The one reader of detections.csv (selfcal/io/detections_csv.py): a marker field's corners and
a board's features as the rows say, in their order, the frames of joints.csv only; anything
wrong is a DatasetError naming the file, the line and the column or the marker."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from selfcal.io.dataset_info import DatasetError
from selfcal.io.detections_csv import board_features, detection_rows, marker_corners

PATH = Path("data") / "detections.csv"
KEEP = np.arange(4)
CAMS = ("left", "right")


def rows_of(markers) -> list[str]:
    """Data lines of ``markers`` [(frame, camera, marker id)] (corners 0-3 each), shuffled."""
    rng = np.random.default_rng(5)
    lines = [f"{i},{c},{m},{k},{rng.uniform(0, 640):.6f},{rng.uniform(0, 480):.6f}"
             for i, c, m in markers for k in range(4)]  # fmt: skip
    return [lines[j] for j in rng.permutation(len(lines))]


def by_row(lines: list[str], corners: bool = True) -> dict:
    """What the rows say, read one by one with Python's csv, int and float (frames 0-3)."""
    out: dict = {}
    for r in csv.reader(lines):
        i, cam, mid = int(r[0]), r[1], int(r[2])
        if i in KEEP:
            if corners:
                out.setdefault((i, cam), {}).setdefault(mid, np.zeros((4, 2)))[int(r[3])] = (
                    float(r[4]), float(r[5]))  # fmt: skip
            else:
                out.setdefault((i, cam), {})[mid] = np.array([[float(r[3]), float(r[4])]])
    return out


def same(a: dict, b: dict) -> bool:
    """Equal dictionaries of corners, keys in the same order and of the same types."""
    if list(a) != list(b) or any(type(x) is not type(y) for k in zip(a, b) for x, y in zip(*k)):
        return False
    return all(list(a[k]) == list(b[k]) and all(np.array_equal(a[k][m], b[k][m]) for m in a[k])
               for k in a)  # fmt: skip


def test_the_corners_of_the_frames_kept_in_the_order_of_their_first_rows():
    markers = [(i, c, m) for i in (3, 0, 7, 2) for c in ("right", "left") for m in (31, 3, 12)]
    lines = rows_of(markers)
    lines.remove(next(x for x in lines if x.startswith("7,left,3,2,")))  # not kept: no check
    got = marker_corners(PATH, lines, KEEP, CAMS)
    assert same(got, by_row(lines))
    assert (7, "left") not in got and len(got) == 6 and all(len(v) == 3 for v in got.values())


def test_a_quoted_row_is_read_unquoted():
    lines = sorted(rows_of([(0, "left", 3)]))
    quoted = ['"0","left",3,{},{},{}'.format(*x.split(",")[3:]) for x in lines]
    assert same(marker_corners(PATH, quoted, KEEP, CAMS), by_row(lines))


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (
            lambda ls: ls + [ls[0]],
            r"line 10: corner 0 of marker 3 in frame 0 \(left\) given twice \(first on line 2\)",
        ),
        (
            lambda ls: [x for x in ls if not x.startswith("0,left,3,2,")],
            r"line \d: marker 3 in frame 0 \(left\) lacks corners \[2\]",
        ),
        (lambda ls: ls[:2] + [""] + ls[2:], "line 4: an empty row"),
        (lambda ls: ["", " "], "line 2: an empty row"),
        (lambda ls: ls + ["0,left,9,4,1.0,2.0"], "line 10, column 'corner': corner 4"),
        (lambda ls: ls + ["0,left,9.0,0,1.0,2.0"], "line 10, column 'marker_id': '9.0' is not"),
        (lambda ls: ls + ["0,left,9,0,1.0,x"], "line 10, column 'v_px': 'x' is not a number"),
        (lambda ls: [x + ",extra" for x in ls], "line 2: 7 columns, the file's are index,"),
        (lambda ls: ls + ["0,left,9,0,nan,2.0"], "line 10, column 'u_px': nan: a pixel"),
        (lambda ls: ls + ["5,left,9,0,1.0,inf"], "line 10, column 'v_px': inf: a pixel"),
        (lambda ls: ls + ["0," + "c" * 70 + ",9,0,1.0,2.0"], "line 10, column 'camera': a name"),
        (lambda ls: ls + ['0,"a,b",9,0,1.0,2.0'], "line 10: the value 'a,b' holds a comma"),
        (
            lambda ls: ls + ["0, left,9,0,1.0,2.0"],
            "line 10, column 'camera': camera ' left' is not one of the dataset's cameras \\['left', 'right'\\]",
        ),
        (lambda ls: ls + ["0,,9,0,1.0,2.0"], "line 10, column 'camera': camera '' is not one"),
    ],
)
def test_a_wrong_row_or_marker_is_named_by_file_line_and_column(change, named):
    lines = change(sorted(rows_of([(0, "left", 3), (0, "right", 3)])))
    with pytest.raises(DatasetError, match=re.escape(str(PATH)) + ", " + named):
        marker_corners(PATH, lines, KEEP, CAMS)


def test_a_boards_features_in_the_order_of_their_rows():
    lines = ["2,left,7,1.5,2.5", "0,left,3,3.0,4.0", "2,left,1,5.0,6.0", "9,left,1,0,0",
             "0,right,3,7.0,8.0"]  # fmt: skip
    got = board_features(PATH, lines, KEEP, CAMS)
    assert same(got, by_row(lines, corners=False)) and list(got[(2, "left")]) == [7, 1]
    with pytest.raises(
        DatasetError, match=r"line 7: feature 3 in frame 0 \(left\) given twice \(first on line 3\)"
    ):
        board_features(PATH, [*lines, "0,left,3,3.0,4.0"], KEEP, CAMS)
    with pytest.raises(DatasetError, match="line 3: 6 columns, the file's are index, camera, "
                                           "feature_id, u_px, v_px"):  # fmt: skip
        board_features(PATH, [lines[0], "0,left,3,0,1.0,2.0"], KEEP, CAMS)


def test_the_rows_written_are_read_back_to_the_written_precision():
    rng = np.random.default_rng(2)
    dets = {"left": {5: rng.uniform(0, 640, (4, 2)), 2: rng.uniform(0, 640, (4, 2))},
            "right": {5: rng.uniform(0, 640, (4, 2))}}  # fmt: skip
    feats = {"left": {7: rng.uniform(0, 640, (1, 2))}}
    for data, board, read in ((dets, False, marker_corners), (feats, True, board_features)):
        rows = detection_rows(3, ("left", "right"), data, board=board)
        got = read(PATH, [",".join(map(str, r)) for r in rows], KEEP, CAMS)
        assert list(got) == [(3, c) for c in data] and list(got[(3, "left")]) == sorted(
            data["left"]
        )
        for (_, cam), ids in got.items():
            assert all(np.allclose(ids[m], data[cam][m], atol=5e-7, rtol=0) for m in ids)


VALID = st.sampled_from(["0", "1", "3", "-1", "7", "2.5", "1e3", " 3", "+2", "0.125"])
NUMBER = st.one_of(VALID, VALID, VALID, VALID, st.sampled_from(["nan", "", "x", "3 ", "1_0"]))
MARKER = st.tuples(st.sampled_from(["0", "1", "3", "7", " 2", "+1"]),
                   st.sampled_from(["left", "right", "", " left"]),
                   st.sampled_from(["3", "-4", "12", "9"]))  # fmt: skip


@settings(max_examples=examples(100), deadline=None)
@given(st.lists(MARKER, max_size=6, unique=True), st.lists(st.lists(NUMBER, min_size=2,
       max_size=2), min_size=4, max_size=4), st.lists(st.lists(NUMBER, min_size=6, max_size=6),
       max_size=1),
       st.randoms())  # fmt: skip
def test_it_reads_what_the_rows_say_or_names_a_line(markers, uv, extra, rnd):
    lines = [",".join([i, c, m, str(k), *uv[k]]) for i, c, m in markers for k in range(4)]
    lines += [",".join(r) for r in extra]
    rnd.shuffle(lines)
    try:
        got = marker_corners(PATH, lines, KEEP, CAMS)
    except DatasetError as exc:
        assert re.match(re.escape(str(PATH)) + r", line \d+", exc.message), exc.message
        return
    assert same(got, by_row(lines))
