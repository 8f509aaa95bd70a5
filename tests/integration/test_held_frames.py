"""A simulated `selfcal run` writes its frames' PNGs on a thread of its own, finishing
beside the calibration (selfcal/acquisition/held_frames.py): the same files as the loop writes them, and
nothing taken is lost on Ctrl-C or a failed write (issue 32)."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest
from test_dataset import FakeRobot, failing_writer, info

import selfcal.io.dataset as dataset_module
from selfcal.acquisition.acquire import AcquisitionError, acquire
from selfcal.acquisition.held_frames import HeldFrames
from selfcal.io.dataset import Dataset, DatasetWriter


def _files(root: Path) -> dict[str, bytes]:
    """The acquisition's files in ``root`` (the frames, joints.csv, dataset.json and a
    simulation's truth.json; temporary files too), by relative path."""
    names = ("joints.csv", "dataset.json", "truth.json")
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and (p.parent.name == "frames" or p.name in names)
    }


def gated_writes(monkeypatch) -> threading.Event:
    """Hold every PNG write until the returned event is set (at most 10 s)."""
    go = threading.Event()
    real = dataset_module._write_png

    def write_png(path, rgb):
        assert go.wait(10)
        real(path, rgb)

    monkeypatch.setattr(dataset_module, "_write_png", write_png)
    return go


class WatchedRobot(FakeRobot):
    """Counts the PNG files on disk at each move; raises KeyboardInterrupt at move ``ctrl_c``."""

    def __init__(self, root: Path, ctrl_c: int | None = None) -> None:
        super().__init__()
        self.root, self.ctrl_c, self.pngs = root, ctrl_c, []

    def move_to(self, joints_deg):
        if self.moves == self.ctrl_c:
            raise KeyboardInterrupt
        self.pngs.append(len(list((self.root / "frames").glob("*.png"))))
        super().move_to(joints_deg)


def test_held_frames_are_written_as_the_loop_writes_them(tmp_path):
    acquire(FakeRobot(), DatasetWriter(tmp_path / "loop", info()))
    with HeldFrames() as held:
        assert acquire(FakeRobot(), DatasetWriter(tmp_path / "held", info()), held=held) == 5
        mine = held.dataset()  # what the calibration takes while the files are written
    assert _files(tmp_path / "held") == _files(tmp_path / "loop")
    ds = Dataset.open(tmp_path / "held")
    assert mine.indices.tolist() == ds.indices.tolist() == [0, 1, 2, 3, 4]
    np.testing.assert_array_equal(mine.joints_deg, ds.joints_deg)


def test_over_the_memory_bound_the_acquisition_waits_for_the_writer(tmp_path, monkeypatch):
    """Past ``max_bytes`` of frames not yet written, a frame handed over waits for the
    oldest to be written."""
    go = gated_writes(monkeypatch)
    w = DatasetWriter(tmp_path, info())
    img = FakeRobot().capture().left
    with HeldFrames(max_bytes=2 * img.nbytes) as held:  # one stereo frame
        held.attach(w, 5, None)
        held.hold(0, np.zeros(5), img, img)  # within the bound: returns at once
        second = threading.Thread(target=held.hold, args=(1, np.ones(5), img, img))
        second.start()
        second.join(0.3)
        assert second.is_alive() and w.n_done == 0  # waits for frame 0
        go.set()
        second.join(10)
        assert not second.is_alive() and w.n_done >= 1
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1]


def test_ctrl_c_after_the_acquisition_writes_every_frame_held(tmp_path, monkeypatch):
    """Ctrl-C while the calibration runs (the files still being written: held here until the
    interrupt) leaves every frame taken on disk, whole; the dataset is complete."""
    acquire(FakeRobot(), DatasetWriter(tmp_path / "loop", info()))
    go = gated_writes(monkeypatch)
    root = tmp_path / "held"
    with pytest.raises(KeyboardInterrupt), HeldFrames() as held:
        acquire(FakeRobot(), DatasetWriter(root, info()), held=held)
        assert held.pending == 5 and (root / "joints.csv").read_text().count("\n") == 1
        assert not list((root / "frames").glob("*.png"))
        go.set()
        raise KeyboardInterrupt
    assert _files(root) == _files(tmp_path / "loop")


def test_ctrl_c_during_the_acquisition_keeps_the_frames_taken_and_resumes(tmp_path):
    root = tmp_path / "held"
    with pytest.raises(AcquisitionError, match=r"frame 3 of 5: interrupted \(Ctrl-C\)\. 3 frames"):
        with HeldFrames() as held:
            acquire(WatchedRobot(root, ctrl_c=3), DatasetWriter(root, info()), held=held)
    assert Dataset.open(root).indices.tolist() == [0, 1, 2]
    with HeldFrames() as held:
        assert acquire(FakeRobot(), DatasetWriter(root, info(), resume=True), held=held) == 2
        assert held.dataset().indices.tolist() == [0, 1, 2, 3, 4]  # the kept ones and the held
    acquire(FakeRobot(), DatasetWriter(tmp_path / "loop", info()))
    assert _files(root) == _files(tmp_path / "loop")


def test_a_held_frame_that_cannot_be_written_stops_the_writing_at_that_frame(tmp_path):
    """As in the loop: the error names the frame and keeps those before it; the frames after
    it are not written (the resume takes them again)."""
    w = failing_writer(tmp_path, 2)
    with pytest.raises(AcquisitionError, match="stopped at frame 2 of 5: disk full.*2 frames"):
        with HeldFrames() as held:
            acquire(FakeRobot(), w, held=held)
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1]
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "0000_left.png", "0000_right.png", "0001_left.png", "0001_right.png"
    ]  # fmt: skip


def test_a_failed_held_write_stops_the_acquisition_at_the_frame_after_the_next(tmp_path):
    """A held frame that cannot be written (disk full) stops the acquisition: the next frame
    handed over raises it and the loop stops at the frame after that, where before the robot
    went on to every posture left (12 planned: all 12 moved) and the error came at the end."""
    w = DatasetWriter(tmp_path, info(m=12))
    real = w.add_frame

    def add_frame(index, *a, **k):
        if index == 2:
            raise OSError("disk full")
        real(index, *a, **k)

    w.add_frame = add_frame  # type: ignore[method-assign]
    held = HeldFrames()

    class Robot(FakeRobot):
        def move_to(self, joints_deg):
            if self.moves == 3:  # frame 2's write is over (failed) before frame 3 is taken
                for _ in range(1000):
                    if not held.pending:
                        break
                    threading.Event().wait(0.01)
            super().move_to(joints_deg)

    robot = Robot()
    with pytest.raises(AcquisitionError, match="stopped at frame 2 of 12: disk full.*2 frames"):
        with held:
            acquire(robot, w, held=held)
    assert robot.moves == 5  # frames 3 and 4 after the failed one, not the 9 left
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1]


@pytest.mark.render
def test_run_calibrates_from_memory_and_ctrl_c_there_leaves_the_files_of_the_loop(
    tmp_path, monkeypatch
):
    """`selfcal run`'s calibration starts from the frames in memory while their PNGs are
    being written (held here until the calibration is done), with the calibration of the
    files the loop writes (`selfcal acquire`); Ctrl-C in it leaves every frame on disk, the
    loop's files byte for byte."""
    from selfcal.config.scenario import load_scenario
    from selfcal.io.calibration import write_calibration
    from selfcal.pipeline import run as pipeline

    s = load_scenario(None, {"trajectory": {"poses": 8}, "validation": {"poses": 3}})
    loop, root = tmp_path / "loop", tmp_path / "run"
    pipeline.run_acquire(s, loop, quiet=True)
    go = gated_writes(monkeypatch)
    real_calibrate = pipeline.calibrate

    def calibrate(where, *, cache, **kwargs):
        assert cache.dataset is not None and len(cache.dataset.indices) == 8
        assert not list((root / "frames").glob("*.png"))
        write_calibration(tmp_path / "memory.json", real_calibrate(where, cache=cache, **kwargs))
        go.set()
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "calibrate", calibrate)
    with pytest.raises(KeyboardInterrupt):
        pipeline.run_all(s, root, quiet=True, figures=False)
    assert _files(root) == _files(loop)
    write_calibration(tmp_path / "files.json", real_calibrate(loop))
    got, want = (json.loads((tmp_path / f).read_text()) for f in ("memory.json", "files.json"))
    got.pop("seconds"), want.pop("seconds")
    assert got == want


@pytest.mark.render
@pytest.mark.slow
def test_run_leaves_the_files_calibration_and_report_of_the_loop(tmp_path):
    """An uninterrupted `selfcal run` (figures off) against `selfcal acquire`, `calibrate`
    and `report` of the same scenario: the same files, byte for byte, but the calibration's
    wall time."""
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline import run as pipeline

    s = load_scenario(None, {"trajectory": {"poses": 8}, "validation": {"poses": 3}})
    loop, root = tmp_path / "loop", tmp_path / "run"
    pipeline.run_acquire(s, loop, quiet=True)
    pipeline.run_calibrate(loop, quiet=True)
    pipeline.run_report(loop, quiet=True)
    pipeline.run_all(s, root, quiet=True, figures=False)
    assert _files(root) == _files(loop)
    names = sorted(p.name for p in root.iterdir() if p.is_file())
    assert names == sorted(p.name for p in loop.iterdir() if p.is_file())
    for name in names:
        if name == "calibration.json":
            got, want = (json.loads((d / name).read_text()) for d in (root, loop))
            got.pop("seconds"), want.pop("seconds")
            assert got == want
        else:
            assert (root / name).read_bytes() == (loop / name).read_bytes(), name
