"""Atomic writes (issue #15): an interrupted write leaves the old file whole and no temporary file
behind; the pipeline's writers go through selfcal.io.atomic."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from selfcal.io import atomic
from selfcal.io.atomic import write_image_atomic, write_text_atomic, write_with_atomic
from selfcal.io.jsonfile import write_json_atomic

REPO = Path(__file__).resolve().parents[2]


class Interrupted(BaseException):
    """Stands for a kill or Ctrl-C in the middle of a write."""


def test_interrupted_write_leaves_the_old_file(tmp_path, monkeypatch):
    p = tmp_path / "calibration.json"
    write_json_atomic(p, {"format": "old"})
    old = p.read_text()
    real_write = os.write

    def half_then_die(fd, data):
        real_write(fd, bytes(data)[: len(data) // 2])
        raise Interrupted

    # the file object writes through os.write on a raw FileIO: die half way through the content
    monkeypatch.setattr(atomic, "open", _opener(half_then_die), raising=False)
    with pytest.raises(Interrupted):
        write_json_atomic(p, {"format": "new", "values": list(range(1000))})
    assert p.read_text() == old
    assert sorted(x.name for x in tmp_path.iterdir()) == ["calibration.json"]


def _opener(write):
    class Half:
        def __init__(self, path, mode):
            self.fh = open(path, mode)  # noqa: SIM115 - closed in __exit__

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            self.fh.flush()
            return write(self.fh.fileno(), data)

        def flush(self):
            self.fh.flush()

        def fileno(self):
            return self.fh.fileno()

    return Half


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    p = tmp_path / "plot.png"
    p.write_bytes(b"old")

    def fails(tmp: Path) -> None:
        tmp.write_bytes(b"partial")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_with_atomic(p, fails)
    assert p.read_bytes() == b"old" and [x.name for x in tmp_path.iterdir()] == ["plot.png"]


def test_text_and_images_round_trip(tmp_path):
    assert write_text_atomic(tmp_path / "r.md", "# report\n").read_text() == "# report\n"
    img = np.random.default_rng(0).integers(0, 255, (8, 10, 3), dtype=np.uint8)
    import cv2

    out = write_image_atomic(tmp_path / "f.png", img)
    np.testing.assert_array_equal(cv2.imread(str(out))[:, :, ::-1], img)
    with pytest.raises(OSError):
        write_image_atomic(tmp_path / "f.nope", img)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["f.png", "r.md"]


# Writers that may write a file directly: the dataset writer (selfcal/io/dataset.py, which keeps its
# own temporary + rename) and `selfcal import` (selfcal/importing/dataset.py: it fills a new dataset
# folder and is being changed in another branch; an interrupted import leaves an incomplete new
# folder, never a damaged result; `selfcal import --bag`, selfcal/ros/bag_import.py with
# selfcal/ros/bag_stage.py, stages the bag's images in that new folder and removes the folder on
# failure), tools that regenerate committed
# files (selfcal/sim/build_models.py, benchmark scripts writing docs, .npz caches and scratch files), the
# emulator transport, and atomic.py itself; the truth journal (selfcal/io/truth.py) is appended a
# line per frame like the dataset's CSV files (its reader drops a partial last line).
ALLOWED = {
    "selfcal/io/atomic.py",
    "selfcal/io/dataset.py",
    "selfcal/io/truth.py",
    "selfcal/calibration/field/calibrate.py",
    "selfcal/importing/dataset.py",
    "selfcal/ros/bag_import.py",
    "selfcal/ros/bag_stage.py",
    "selfcal/sim/build_models.py",
    "selfcal/benchmarks/tracker/compare.py",
    "selfcal/benchmarks/timing/ros.py",
    "selfcal/benchmarks/tracker/pybotics_fit.py",
    "selfcal/benchmarks/handeye/opencv4.py",  # runs in OpenCV 4's environment, without selfcal
}
DIRECT = re.compile(
    r"\.write_text\(|\.write_bytes\(|open\([^)]*[\"'][wa]b?[\"']|imwrite\(|savefig\("
)


def test_the_pipeline_writes_through_calib_io_atomic():
    found = []
    for pkg in ("selfcal",):
        for f in sorted((REPO / pkg).rglob("*.py")):
            rel = f.relative_to(REPO).as_posix()
            if rel in ALLOWED or rel.startswith("selfcal/studies/"):
                continue
            for i, line in enumerate(f.read_text().splitlines(), 1):
                # a figure drawn into memory (the figure worker's warm-up) writes no file
                in_memory = "savefig(io.BytesIO()" in line
                if DIRECT.search(line) and "save_figure" not in line and not in_memory:
                    found.append(f"{rel}:{i}: {line.strip()}")
    # the one savefig, and the figure's own PNG encoding, are inside
    # selfcal.plots.plotting.save_figure, through write_with_atomic
    plotting = REPO / "selfcal/plots/plotting.py"
    assert found == [
        f"selfcal/plots/plotting.py:{_line_of(plotting, 'tmp.write_bytes(figure_png(fig))')}: "
        "return write_with_atomic(path, lambda tmp: tmp.write_bytes(figure_png(fig)))",
        f"selfcal/plots/plotting.py:{_line_of(plotting, 'fig.savefig(')}: "
        "return write_with_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))",
    ], "\n".join(found)


def _line_of(path: Path, text: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if text in line)
