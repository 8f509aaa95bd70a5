"""The stereo camera adapter over cv2.VideoCapture, on image sequences and with the emulator."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from selfcal.hw.acl.robot import AclRobot
from selfcal.hw.cameras import Camera, CameraError, StereoCamera, source_kind
from selfcal.hw.emulator.backends import KinematicBackend
from selfcal.hw.emulator.server import AclEmulator
from selfcal.robot.definition import load_robot
from selfcal.robot.interface import StereoPair


def _write(path, rgb):
    assert cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))


def _img(value, w=64, h=48):
    img = np.zeros((h, w, 3), np.uint8)
    img[..., 0] = value  # red channel carries the frame id: catches BGR/RGB mix-ups too
    img[..., 2] = 255 - value
    return img


def test_source_kind():
    assert source_kind("0") == "device" and source_kind(1) == "device"
    assert source_kind("frames/%04d_left.png") == "sequence"
    assert source_kind("http://127.0.0.1:8080/left.mjpg") == "stream"
    assert source_kind("video.avi") == "stream"


def test_latest_mode_reads_the_newest_frame_in_rgb(tmp_path):
    pat = str(tmp_path / "%04d_left.png")
    cam = Camera(pat, name="left", expected_size=(64, 48))
    _write(tmp_path / "0000_left.png", _img(10))
    rgb, meta = cam.read()
    assert rgb.shape == (48, 64, 3) and rgb.dtype == np.uint8
    assert tuple(rgb[0, 0]) == (10, 0, 245) and meta["frame_index"] == 0
    for i in (1, 2, 3):
        _write(tmp_path / f"{i:04d}_left.png", _img(10 * (i + 1)))
    rgb, meta = cam.read()
    assert rgb[0, 0, 0] == 40 and meta["frame_index"] == 3
    rgb, _ = cam.read(1)
    assert rgb[0, 0, 0] == 20


def test_next_mode_replays_then_reports_exhaustion(tmp_path):
    for i in range(3):
        _write(tmp_path / f"{i:04d}_x.png", _img(i + 1))
    cam = Camera(str(tmp_path / "%04d_x.png"), sequence_mode="next", name="left")
    assert [cam.read()[0][0, 0, 0] for _ in range(3)] == [1, 2, 3]
    with pytest.raises(CameraError, match="left camera gave no frame.*exhausted"):
        cam.read()
    cam.close()


def test_stereo_pair_uses_one_index_for_both(tmp_path):
    for i in range(3):
        _write(tmp_path / f"{i:04d}_left.png", _img(i + 1))
    for i in range(2):  # right lags by one frame: the pair must not mix postures
        _write(tmp_path / f"{i:04d}_right.png", _img(100 + i + 1))
    cams = StereoCamera.from_sources(
        [str(tmp_path / "%04d_left.png"), str(tmp_path / "%04d_right.png")]
    )
    pair = cams.capture()
    assert isinstance(pair, StereoPair)
    assert (pair.left[0, 0, 0], pair.right[0, 0, 0]) == (2, 102)
    assert pair.meta["left_frame_index"] == pair.meta["right_frame_index"] == 1


def test_errors(tmp_path):
    # no frame at all
    with pytest.raises(CameraError, match=r"no frame: image sequence .*0000_left.png"):
        Camera(str(tmp_path / "%04d_left.png"), name="left", timeout_s=0.05).read()
    # wrong resolution
    _write(tmp_path / "0000_left.png", _img(1, w=32, h=24))
    with pytest.raises(CameraError, match=r"gives 32x24 frames but 64x48 are expected"):
        Camera(str(tmp_path / "%04d_left.png"), expected_size=(64, 48)).read()
    # left and right sizes differ
    _write(tmp_path / "0000_right.png", _img(1, w=64, h=48))
    cams = StereoCamera.from_sources(
        [str(tmp_path / "%04d_left.png"), str(tmp_path / "%04d_right.png")]
    )
    with pytest.raises(CameraError, match="different sizes"):
        cams.capture()
    # 16-bit images are refused, grey ones converted
    assert cv2.imwrite(str(tmp_path / "0000_d.png"), np.zeros((4, 4), np.uint16))
    with pytest.raises(CameraError, match="uint16"):
        Camera(str(tmp_path / "%04d_d.png")).read()
    assert cv2.imwrite(str(tmp_path / "0000_g.png"), np.full((4, 4), 7, np.uint8))
    rgb, _ = Camera(str(tmp_path / "%04d_g.png")).read()
    assert rgb.shape == (4, 4, 3) and np.all(rgb == 7)
    # a device that does not exist, a stream nobody serves
    with pytest.raises(CameraError, match="cannot open left camera '97'"):
        Camera("97", name="left")
    with pytest.raises(
        CameraError, match="cannot open right camera 'http://127.0.0.1:9/none.mjpg'"
    ):
        Camera("http://127.0.0.1:9/none.mjpg", name="right")
    with pytest.raises(ValueError, match="two sources"):
        StereoCamera.from_sources(["0"])


class PaintingBackend(KinematicBackend):
    """Kinematic backend whose images encode the base angle, so a test can tell postures apart."""

    def capture(self) -> StereoPair:
        w, h = self.image_size
        v = int(round(self.joints_deg[0])) + 100
        left = np.full((h, w, 3), v, np.uint8)
        return StereoPair(left, left // 2, {})


def test_robot_capture_sees_the_posture_it_moved_to():
    with AclEmulator(
        PaintingBackend(image_size=(80, 60)), move_speed_deg_s=2000.0, tcp_port=None
    ) as emu:
        cfg = {"port": emu.pty_path, "cameras": list(emu.camera_sources), "camera_size": [80, 60]}
        with AclRobot.from_config(cfg) as robot:
            home = np.degrees(load_robot("er4u-vendor").home)
            for base in (0.0, 25.0, -40.0):
                robot.move_to(home + [base, 0, 0, 0, 0])
                pair = robot.capture()
                assert pair.left[0, 0, 0] == int(base) + 100
                assert pair.right[0, 0, 0] == (int(base) + 100) // 2
