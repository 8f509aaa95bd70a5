"""joints.csv rows missing, cut off or not finite, and frames that are copies of each other: each
named before anything is estimated (issue #15). Before: missing and cut-off rows were skipped
without a word, NaN ended in a LinAlgError, a copied frame was weighted twice (analytic path) or
failed the joint refinement naming no frame (rendered path)."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
from analytic_dataset import acquire_analytic, run

from selfcal.calibration.field.calibrate import calibrate, detect_dataset
from selfcal.calibration.frame_checks import NEAR_PX, alike_frames, unused_frames_message
from selfcal.io.dataset import Dataset, DatasetError


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """10 postures on the analytic path (detections, no rendering)."""
    return acquire_analytic(tmp_path_factory.mktemp("checks") / "ds", 10, 3)


def edited(src, dst, joints=None, detections=None):
    """A copy of ``src`` whose joints.csv text (and detections.csv text) is ``f(text)``."""
    shutil.copytree(src, dst)
    for name, f in (("joints.csv", joints), ("detections.csv", detections)):
        if f is not None:
            (dst / name).write_text(f((dst / name).read_text()))
    return dst


def drop(*frames):
    def f(text):
        lines = text.splitlines()
        return "\n".join(r for r in lines if r.split(",")[0] not in {str(i) for i in frames}) + "\n"

    return f


def test_missing_rows_are_an_error_listing_the_frames(capsys, dataset, tmp_path):
    ds = edited(dataset, tmp_path / "missing", joints=drop(2, 5))
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert "joints.csv: frames 2, 5 of the 10 planned have no row" in err
    assert "--allow-missing-frames" in err and not (ds / "calibration.json").exists()
    # with the option: a warning that lists them, and the other 8 frames calibrated
    code, out, err = run(capsys, "calibrate", ds, "--allow-missing-frames")
    assert code == 0 and "warning: " in err and "frames 2, 5 of the 10 planned" in err
    doc = json.loads((ds / "calibration.json").read_text())
    assert doc["dataset"]["frames_used"] == 8 and "frames 2, 5" in doc["warnings"][0]


def test_cut_off_rows_are_named_by_line_and_frame(dataset, tmp_path):
    def cut(text):  # the last row loses its end (an interrupted write), frame 4 keeps 3 values
        lines = text.splitlines()
        lines[5] = ",".join(lines[5].split(",")[:4])
        return "\n".join(lines)[:-5]

    ds = Dataset.open(edited(dataset, tmp_path / "cut", joints=cut))
    assert ds.missing == (4, 9)
    with pytest.raises(DatasetError) as exc:
        ds.check_complete()
    msg = str(exc.value)
    assert "frames 4, 9 of the 10 planned have no row" in msg
    assert "line 6 (frame 4: 3 values; the robot has 5 joints)" in msg
    assert "line 11 (frame 9: no newline: an interrupted write" in msg
    assert "frames 4, 9" in ds.check_complete(allow_missing=True)[0]


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "NaN"])
def test_non_finite_joints_name_file_line_and_joint(capsys, dataset, tmp_path, bad):
    def poison(text):
        lines = text.splitlines()
        cells = lines[4].split(",")
        cells[3] = bad
        lines[4] = ",".join(cells)
        return "\n".join(lines) + "\n"

    ds = edited(dataset, tmp_path / "nan", joints=poison)
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert (
        f"joints.csv: line 5 (frame '3'): q3_deg = {float(bad)}: joint readings must be finite"
        in err
    )


@pytest.mark.parametrize(
    ("row", "match"),
    [("3,1,2,3,4,5,6", "6 values, the robot has 5 joints"), ("3,1,2,x,4,5", "not a number"),
     ("2,1,2,3,4,5", "frame 2 appears twice")],
)  # fmt: skip
def test_malformed_rows_name_file_and_line(dataset, tmp_path, row, match):
    def put(text):
        lines = text.splitlines()
        lines[4] = row
        return "\n".join(lines) + "\n"

    with pytest.raises(DatasetError, match=match) as exc:
        Dataset.open(edited(dataset, tmp_path / "bad", joints=put))
    assert "joints.csv: line 5" in str(exc.value)


def copy_frame(src_frame, dst_frame, *, joints=True, corners=True, shift_px=0.0):
    """Edits that make frame ``dst_frame`` a copy of ``src_frame`` (its joints row, its corners
    moved by ``shift_px`` of seeded noise)."""

    def j(text):
        lines = text.splitlines()
        lines[dst_frame + 1] = ",".join([str(dst_frame), *lines[src_frame + 1].split(",")[1:]])
        return "\n".join(lines) + "\n"

    def d(text):
        rng = np.random.default_rng(0)
        lines = text.splitlines()
        keep = [r for r in lines[1:] if r.split(",")[0] != str(dst_frame)]
        new = []
        for r in lines[1:]:
            c = r.split(",")
            if c[0] == str(src_frame):
                u, v = (float(x) + shift_px * rng.standard_normal() for x in c[4:])
                new.append(",".join([str(dst_frame), *c[1:4], f"{u:.6f}", f"{v:.6f}"]))
        return "\n".join([lines[0], *keep, *new]) + "\n"

    return {"joints": j if joints else None, "detections": d if corners else None}


def test_a_copied_frame_is_named_before_the_calibration(capsys, dataset, tmp_path):
    ds = edited(dataset, tmp_path / "copy", **copy_frame(3, 7))
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert "frames 3 and 7 show the same corners (identical) and the same joint readings: " in err
    assert "frame 7 is a copy of frame 3" in err and " -- remove" in err


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"joints": False}, r"\(identical\) although their joint readings differ by up to"),
        ({"joints": False, "shift_px": 0.01}, r"within 0.01\d px RMS\) although"),
        ({"corners": False}, "have the same joint readings but different images"),
    ],
)
def test_a_stale_image_or_joints_row_is_named(dataset, tmp_path, edit, match):
    """Corners 0.01 px apart (a re-encoded copy) count as the same image; the joint readings
    alone equal: a copied row or a read-back that did not change."""
    ds = Dataset.open(edited(dataset, tmp_path / "stale", **copy_frame(3, 7, **edit)))
    found = alike_frames(ds.indices, ds.joints_deg, detect_dataset(ds).detections, ds.info.cameras)
    assert len(found) == 1 and found[0].startswith("frames 3 and 7 ")
    assert re.search(match, found[0]), found[0]


def test_distinct_frames_are_not_named(dataset):
    ds = Dataset.open(dataset)
    dets = detect_dataset(ds).detections
    assert alike_frames(ds.indices, ds.joints_deg, dets, ds.info.cameras) == []
    assert NEAR_PX < 0.1  # far below the 54 px that separate two postures (see NEAR_PX)


def test_joints_in_radians_where_degrees_are_declared(capsys, dataset, tmp_path):
    """Before: an IdentificationError that blamed the data, not the unit."""

    def to_radians(text):
        lines = text.splitlines()
        rows = [r.split(",") for r in lines[1:]]
        rows = [[c[0], *(f"{np.radians(float(v)):.9f}" for v in c[1:])] for c in rows]
        return "\n".join([lines[0], *(",".join(c) for c in rows)]) + "\n"

    ds = edited(dataset, tmp_path / "rad", joints=to_radians)
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert "joints.csv: the joint readings look like radians" in err
    assert " -- write joints.csv in degrees" in err


def test_joints_rows_of_other_frames_are_named(dataset, tmp_path):
    def swap_rows(text):  # frames 2 and 6 exchange their joints (the indices stay)
        lines = text.splitlines()
        a, b = lines[3].split(","), lines[7].split(",")
        lines[3], lines[7] = ",".join([a[0], *b[1:]]), ",".join([b[0], *a[1:]])
        return "\n".join(lines) + "\n"

    ds = edited(dataset, tmp_path / "swap", joints=swap_rows)
    with pytest.raises(DatasetError, match=r"2 frame\(s\) read joints more than 5 deg from their "
                       r"planned postures \(frames 2, 6; worst frame [26]: q\d_deg = ") as exc:  # fmt: skip
        calibrate(ds)
    assert "rows or columns out of order" in str(exc.value)


def copy_camera(frame, src, dst, from_frame=None):
    """An edit of detections.csv that replaces camera ``dst``'s corners of ``frame`` by camera
    ``src``'s (of ``from_frame``, default the same frame)."""
    from_frame = frame if from_frame is None else from_frame

    def d(text):
        lines = text.splitlines()
        keep = [r for r in lines[1:] if r.split(",")[:2] != [str(frame), dst]]
        new = [",".join([str(frame), dst, *r.split(",")[2:]])
               for r in lines[1:] if r.split(",")[:2] == [str(from_frame), src]]  # fmt: skip
        return "\n".join([lines[0], *keep, *new]) + "\n"

    return {"detections": d}


@pytest.mark.parametrize(("src", "dst"), [("left", "right"), ("right", "left")])
def test_one_camera_copied_over_the_other_is_named(capsys, dataset, tmp_path, src, dst):
    """#33: the right image a copy of the left was dropped without a word (29 of 30 frames used,
    skipped_images empty); the left a copy of the right failed the outlier rejection, exit 3,
    naming no frame."""
    ds = edited(dataset, tmp_path / "copy", **copy_camera(4, src, dst))
    code, out, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 2 and out == ""
    assert "frame 4: the right image shows the same corners as the left image" in err
    assert "(identical): one camera's image was copied over the other's" in err


@pytest.mark.slow
def test_a_frame_the_camera_stage_drops_is_named(dataset, tmp_path):
    """#33: frame 3's right image of another frame (5): the camera stage cannot register the frame
    and leaves it out; a warning and calibration.json name it (before: 9 of 10 used, no word)."""
    ds = edited(dataset, tmp_path / "other", **copy_camera(3, "right", "right", from_frame=5))
    with pytest.warns(UserWarning, match=r"1 of 10 frame\(s\) not used by the calibration: 3;"):
        res = calibrate(ds, method="two-stage")
    assert res.dataset.frames_used == 9 and res.dataset.unused_frames == (3,)
    assert any("not used by the calibration: 3;" in w for w in res.warnings)
    assert res.to_json()["dataset"]["unused_frames"] == [3]


def test_unused_frames_are_named_with_their_images_without_markers():
    msg = unused_frames_message(np.arange(10, 16), np.array([0, 1, 3, 5]), ("0012_left",))
    assert msg.startswith("2 of 6 frame(s) not used by the calibration: 12 (an image without ")
    assert ", 14; the camera stage could not register them" in msg
    assert unused_frames_message(np.arange(4), np.arange(4), ()) == ""
