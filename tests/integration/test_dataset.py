"""Dataset folder: frames are written as they are taken, interrupted runs keep them and resume."""

import dataclasses

import numpy as np
import pytest

from selfcal.acquisition.acquire import AcquisitionError, acquire
from selfcal.io.dataset import Dataset, DatasetError, DatasetWriter, read_gray
from selfcal.io.dataset_info import DatasetInfo
from selfcal.robot.interface import StereoPair


def info(observation="images", m=5):
    rng = np.random.default_rng(0)
    return DatasetInfo(
        robot_model="er4u-paper",
        resolution=(64, 48),
        dictionary="DICT_4X4_50",
        scale_ids=(48, 49),
        scale_length_m=0.2,
        observation=observation,
        planned_joints_deg=rng.uniform(-10, 10, (m, 5)),
        validation_joints_deg=rng.uniform(-10, 10, (3, 5)),
    )


class FakeRobot:
    """A Robot that fails on a chosen frame (to test interruption)."""

    model_name = "er4u-paper"

    def __init__(self, fail_at=None):
        self.q = np.zeros(5)
        self.fail_at = fail_at
        self.moves = 0

    def home(self):
        self.q = np.zeros(5)

    def move_to(self, joints_deg):
        if self.fail_at is not None and self.moves == self.fail_at:
            raise OSError("serial link lost")
        self.moves += 1
        self.q = np.asarray(joints_deg, dtype=float)

    def joints(self):
        return np.round(self.q, 3)

    def capture(self):
        img = np.full((48, 64, 3), int(abs(self.q[0]) * 10) % 255, np.uint8)
        return StereoPair(img, img.copy())

    def close(self):
        pass


def test_images_round_trip(tmp_path):
    w = DatasetWriter(tmp_path, info())
    assert acquire(FakeRobot(), w) == 5
    ds = Dataset.open(tmp_path)
    assert ds.indices.tolist() == [0, 1, 2, 3, 4]
    np.testing.assert_allclose(ds.joints_deg, np.round(info().planned_joints_deg, 3), atol=1e-6)
    imgs = list(ds.iter_images())
    assert len(imgs) == 10 and imgs[0][2].shape == (48, 64)


def test_interrupted_run_keeps_frames_and_resumes(tmp_path):
    w = DatasetWriter(tmp_path, info())
    with pytest.raises(AcquisitionError, match="3 frames are kept.*--resume"):
        acquire(FakeRobot(fail_at=3), w)
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1, 2]
    with pytest.raises(DatasetError, match="--resume"):
        DatasetWriter(tmp_path, info())
    w2 = DatasetWriter(tmp_path, info(), resume=True)
    assert w2.n_done == 3
    assert acquire(FakeRobot(), w2) == 2
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1, 2, 3, 4]


def test_resume_with_other_scenario_is_refused(tmp_path):
    DatasetWriter(tmp_path, info(m=5))
    with pytest.raises(DatasetError, match="another scenario"):
        DatasetWriter(tmp_path, info(m=6), resume=True)


def test_partial_detection_rows_are_dropped_on_resume(tmp_path):
    w = DatasetWriter(tmp_path, info("detections"))
    c = np.arange(8.0).reshape(4, 2)
    w.add_frame(0, np.zeros(5), detections={"left": {3: c}, "right": {3: c + 1}})
    # a crash after writing detections of frame 1 but before its joints row:
    with open(tmp_path / "detections.csv", "a") as fh:
        fh.write("1,left,3,0,1.0,2.0\n1,left,3,1,1.0,")
    w2 = DatasetWriter(tmp_path, info("detections"), resume=True)
    assert w2.done == [0]
    dets = Dataset.open(tmp_path).read_detections()
    assert set(dets) == {(0, "left"), (0, "right")}
    np.testing.assert_array_equal(dets[(0, "right")][3], c + 1)


def test_missing_frame_is_a_clear_error(tmp_path):
    acquire(FakeRobot(), DatasetWriter(tmp_path, info()))
    (tmp_path / "frames" / "0002_right.png").unlink()
    with pytest.raises(DatasetError, match="0002_right.png is missing"):
        list(Dataset.open(tmp_path).iter_images())


def test_a_moved_image_names_its_path_and_the_fix_without_opencvs_warning(tmp_path, capfd):
    # a new user's `selfcal plan --add 5 DS` on a dataset whose frames/ had moved: OpenCV's
    # "[ WARN:0@4.6] global loadsave.cpp:278 findDecoder imread_(...)" lines first, then an error
    # naming the bare file name with a fix for calibrate alone ("re-acquire it" an import too)
    acquire(FakeRobot(), DatasetWriter(tmp_path, info()))
    gone = tmp_path / "frames" / "0002_right.png"
    gone.unlink()
    capfd.readouterr()
    with pytest.raises(DatasetError) as err:
        read_gray(gone, 2)
    assert capfd.readouterr().err == ""
    assert err.value.message.startswith(f"{gone}: frame 0002_right.png is missing")
    assert f"{tmp_path / 'joints.csv'} lists frame 2" in err.value.message
    assert "sources.csv" in err.value.fix and "--allow-missing-frames" in err.value.fix


def test_not_a_dataset(tmp_path):
    with pytest.raises(DatasetError, match="no dataset.json") as err:
        Dataset.open(tmp_path)
    # the fix names the real-data route too: `selfcal check cal nothere` told a user of their own
    # images to make the folder with `selfcal acquire CONFIG` alone (session 25's new-user trip)
    assert err.value.message == f"{tmp_path}: no dataset.json: not a dataset folder"
    assert "`selfcal import ... --out DIR` (docs/own-data.md)" in err.value.fix
    assert "`selfcal acquire CONFIG --out DIR`" in err.value.fix
    # and a damaged dataset.json's fix, which said "re-acquire it" to an imported dataset too
    (tmp_path / "dataset.json").write_text("{}")
    with pytest.raises(DatasetError) as err:
        Dataset.open(tmp_path)
    assert "`selfcal import ... --out DIR` (your own images)" in str(err.value.fix), err.value


def test_one_camera_dataset_writes_and_reads_its_frames(tmp_path):
    one = dataclasses.replace(info(m=2), cameras=("cam0",))
    w = DatasetWriter(tmp_path, one)
    img = np.full((48, 64), 7, np.uint8)
    with pytest.raises(DatasetError, match=r"no image of camera\(s\) \['cam0'\]"):
        w.add_frame(0, np.zeros(5), left=img, right=img)
    for i in range(2):
        w.add_frame(i, np.zeros(5), images={"cam0": img})
    ds = Dataset.open(tmp_path)
    got = list(ds.iter_images())
    assert [(i, c) for i, c, _ in got] == [(0, "cam0"), (1, "cam0")]
    assert ds.frame_paths(1) == (tmp_path / "frames" / "0001_cam0.png",)
    np.testing.assert_array_equal(got[0][2], img)


def failing_writer(root, at: int) -> DatasetWriter:
    """A writer whose frame ``at`` cannot be written (``OSError("disk full")``)."""
    w = DatasetWriter(root, info())
    real = w.add_frame

    def add_frame(index, *a, **k):
        if index == at:
            raise OSError("disk full")
        real(index, *a, **k)

    w.add_frame = add_frame  # type: ignore[method-assign]
    return w


def test_a_frame_that_cannot_be_written_stops_the_acquisition_at_that_frame(tmp_path):
    """Frames are written by a worker thread while the robot moves on: a write failure still
    names its own frame and keeps the frames before it."""
    w = failing_writer(tmp_path, 2)
    with pytest.raises(AcquisitionError, match="stopped at frame 2 of 5: disk full.*2 frames"):
        acquire(FakeRobot(), w)
    assert Dataset.open(tmp_path).indices.tolist() == [0, 1]


def test_a_frame_whose_second_image_fails_on_the_image_thread_gets_no_joints_row(
    tmp_path, monkeypatch
):
    """The acquisition writes a frame's second image on a thread of its own: its failure is
    the frame's, and the frame is not listed (its joints row follows every image)."""
    import selfcal.io.dataset as dataset_module

    real = dataset_module._write_png

    def write_png(path, rgb):
        if path.name == "0001_right.png":
            raise OSError("disk full")
        real(path, rgb)

    monkeypatch.setattr(dataset_module, "_write_png", write_png)
    with pytest.raises(AcquisitionError, match="stopped at frame 1 of 5: disk full.*1 frames"):
        acquire(FakeRobot(), DatasetWriter(tmp_path / "a", info()))
    assert Dataset.open(tmp_path / "a").indices.tolist() == [0]
    monkeypatch.setattr(dataset_module, "_write_png", real)
    acquire(FakeRobot(), DatasetWriter(tmp_path / "b", info()))
    w = DatasetWriter(tmp_path / "c", info())
    for i, q in enumerate(info().planned_joints_deg):  # one thread, as before
        pair = FakeRobot()
        pair.move_to(q)
        w.add_frame(i, pair.joints(), left=pair.capture().left, right=pair.capture().right)
    for name in sorted(p.name for p in (tmp_path / "b" / "frames").iterdir()):
        assert (tmp_path / "b" / "frames" / name).read_bytes() == (
            tmp_path / "c" / "frames" / name).read_bytes()  # fmt: skip


def test_each_camera_keeps_its_own_model_and_free_parameters(tmp_path):
    """dataset.json holds a model per camera; the field self-calibration of a dataset of mixed
    models estimates each camera's own (a CameraSet), of one model the shared camera."""
    from selfcal.calibration.field.calibrate import dataset_camera
    from selfcal.camera import CameraSet
    from selfcal.io.dataset_info import read_dataset_info, write_dataset_info

    models = (("opencv", ("fx", "mu", "cx", "cy", "k1", "k2")), ("pinhole", ("fx", "mu")))
    mixed = dataclasses.replace(info(m=6), cameras=("left", "right"), camera_models=models)
    write_dataset_info(tmp_path / "dataset.json", mixed)
    back = read_dataset_info(tmp_path / "dataset.json")
    assert back.camera_models == models and back.model_of("right") == models[1]
    same = dataclasses.replace(info(), cameras=("a", "b"))
    assert same.camera_models is None and same.model_of("b") == ("pinhole", ("fx", "mu"))
    cams = dataset_camera(back)
    assert isinstance(cams, CameraSet) and cams.names == ("left", "right")
    assert [(c.model_name, c.free) for c in cams.cameras] == list(models)
    assert not isinstance(dataset_camera(same), CameraSet)
