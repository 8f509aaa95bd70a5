"""``selfcal export DATASET --bag OUT``: a dataset (simulated or imported) as a ROS bag, for the
tools that read bags (ROS robot_calibration, Kalibr, MoveIt's hand-eye calibration).

Timeline (stamps in integer ns from :data:`T0_NS`): frame ``k``'s images are stamped
``t_k = T0 + k (2 hold + move)``; the arm rests at frame ``k``'s joint reading from
``t_k - hold`` to ``t_k + hold`` and moves to the next one in ``move`` seconds on a minimum-jerk
profile. ``joint_states`` (``sensor_msgs/JointState``, the robot's joint names, rad / m) are
published at ``rate_hz`` and at every image stamp (the frame's reading exactly). Per camera
``/NAME/image_raw`` (raw mono8, mono16 or bgr8, the dataset's pixels unchanged) and
``/NAME/camera_info`` at the same stamps: the calibrated camera when the dataset folder holds a
``calibration.json`` in ROS camera_calibration's convention (K, D, R = I, P = [K' | 0] with K'
the rectified camera matrix, as ``selfcal export --format camera_info`` writes it), otherwise
uncalibrated (K all zeros, the model's ``distortion_model``).
``/robot_description`` (``std_msgs/String``, once at the start): the robot's NOMINAL URDF.
``/tf_static`` (once at the start) and ``/tf`` (at every joint state): the calibrated chain when
the folder holds a ``calibration.json``, else the nominal one (:mod:`selfcal.ros.bag_chain`); the
images' and camera_infos' ``frame_id`` is the camera's frame in it (``camera_optical_frame`` for
one camera, ``cam_left``, ``cam_right`` for a rig: :func:`selfcal.ros.bag_chain.camera_frames`).
Truth never goes into the bag (``truth.json`` is not read).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from selfcal.camera import CameraModel, Pinhole, entry
from selfcal.camera.registry import ROS_D_NAMES
from selfcal.choices import JOINT_TOPIC
from selfcal.export.camera import camera_matrix, distortion, rectified_matrix
from selfcal.export.deploy import deploy_chain
from selfcal.export.urdf import to_urdf
from selfcal.io.board_calibration import calibration_kind, read_board_calibration
from selfcal.io.calibration import read_calibration
from selfcal.io.dataset import Dataset
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.ros.bag_chain import bag_chain, camera_frames, moving_edges, static_edges
from selfcal.ros.bag_rest import NS
from selfcal.ros.rosbag import FORMATS, BagError, BagWriter, CameraInfo

__all__ = ["BagExport", "export_bag", "nominal_urdf", "bag_format_for", "T0_NS", "JOINT_TOPIC"]

T0_NS = 1_700_000_000 * NS
"""Stamp of the first image (ns since the Unix epoch; a fixed date keeps bags reproducible)."""


@dataclass(frozen=True)
class BagExport:
    """What :func:`export_bag` wrote: the bag, its format, frames, cameras and message counts."""

    path: Path
    format: str
    frames: int
    cameras: tuple[str, ...]
    joint_states: int
    duration_s: float

    def to_json(self) -> dict:
        return {"out": str(self.path), "format": self.format, "frames": self.frames,
                "cameras": list(self.cameras), "joint_states": self.joint_states,
                "duration_s": self.duration_s}  # fmt: skip


def bag_format_for(out: str | Path, fmt: str | None) -> str:
    """``fmt``, or from ``out``: ``.bag`` -> ros1, ``.mcap`` -> mcap (a bare file), anything
    else -> ros2 (a bag folder)."""
    if fmt is not None:
        return fmt
    return {".bag": "ros1", ".mcap": "mcap"}.get(Path(out).suffix, "ros2")


def nominal_urdf(ds: Dataset) -> str:
    """The robot's nominal URDF: its own URDF file when it was given as one (or by a robot TOML's
    ``[urdf]`` table), else the nominal DH chain written by :func:`selfcal.export.urdf.to_urdf`."""
    src = ds.robot_source
    if isinstance(src, Path) and src.suffix == ".urdf":
        return src.read_text()
    robot = load_robot(src)
    if isinstance(src, Path) and robot.convention == "urdf":
        from selfcal.tomlfile import read_toml

        table = read_toml(src).get("urdf", {})
        return (src.parent / str(table["file"])).read_text()
    return _dh_urdf(robot, len(ds.info.cameras))


def _dh_urdf(robot: RobotDef, cameras: int) -> str:
    dep = deploy_chain(nominal_mcpc(robot).with_tool(robot.T_flange_cam), robot,
                       source="nominal robot model")  # fmt: skip
    with warnings.catch_warnings():
        # a nominal frame at exactly +-90 deg pitch: scipy's rpy sets the third angle to zero and
        # still represents the rotation; its warning would only puzzle the user
        warnings.filterwarnings("ignore", "Gimbal lock detected", UserWarning)
        return to_urdf(dep, calibrated=False, cameras=cameras)


def _camera_infos(ds: Dataset) -> dict[str, CameraInfo]:
    """Each camera's CameraInfo: the dataset's calibration when it holds one, else uncalibrated."""
    info = ds.info
    cams: dict[str, CameraModel] = {}
    cal = ds.root / "calibration.json"
    if cal.is_file():
        if calibration_kind(cal) == "board":
            res = read_board_calibration(cal)
            cams = dict(zip(res.camera_names, res.cameras))
        else:
            res_ = read_calibration(cal)  # each camera's own intrinsics, or the shared ones
            cams = {c: res_.intrinsics_of(i).camera() for i, c in enumerate(info.cameras)}
    out = {}
    for c in info.cameras:
        w, h = info.resolution_of(c)
        cam = cams.get(c)
        if isinstance(cam, Pinhole):
            model, D = distortion(cam)
            K, K_rect = camera_matrix(cam).ravel(), rectified_matrix(cam).ravel()
        else:
            model = entry(info.camera_model).ros[0]
            D, K = np.zeros(len(ROS_D_NAMES[model])), np.zeros(9)
            K_rect = K
        out[c] = CameraInfo(w, h, model, tuple(map(float, D)), tuple(map(float, K)),
                            tuple(map(float, K_rect)))  # fmt: skip
    return out


def _min_jerk(s: np.ndarray) -> np.ndarray:
    return s**3 * (10 - 15 * s + 6 * s**2)


def export_bag(
    dataset: str | Path,
    out: str | Path,
    fmt: str | None = None,
    *,
    hold_s: float = 0.5,
    move_s: float = 1.0,
    rate_hz: float = 100.0,
    joint_topic: str = JOINT_TOPIC,
) -> BagExport:
    """Write the dataset folder ``dataset`` as the bag ``out`` (module docstring) in ``fmt``
    (:data:`selfcal.ros.rosbag.FORMATS`; None: :func:`bag_format_for`).

    Raises:
        selfcal.io.dataset.DatasetError: not a complete dataset.
        selfcal.ros.rosbag.BagError: a dataset without images (the analytic path's detections), an
            existing ``out``, an unknown format.
    """
    ds = Dataset.open(dataset)
    fmt = bag_format_for(out, fmt)
    if fmt not in FORMATS:
        raise BagError(f"--format {fmt}", fix=f"use one of {', '.join(FORMATS)}")
    if ds.info.observation != "images":
        raise BagError(
            f"{ds.root}: the dataset holds detections (the analytic path), no images to put in a bag",
            fix="acquire with rendering on ([noise] render = true) to export a bag",
        )
    robot = load_robot(ds.robot_source)
    paths = ds.image_paths()  # raises for a missing frame before the bag is created
    q = np.radians(np.asarray(ds.joints_deg, float))  # joints.csv: np.degrees of the SI values
    n = len(q)
    period = int(round((2 * hold_s + move_s) * NS))
    hold, move = int(round(hold_s * NS)), int(round(move_s * NS))
    stamps = T0_NS + period * np.arange(n, dtype=np.int64)
    start, end = int(stamps[0]) - hold, int(stamps[-1]) + hold
    step = int(round(NS / rate_hz))
    ticks = np.union1d(np.arange(start, end + 1, step, dtype=np.int64), stamps)
    infos = _camera_infos(ds)
    by_frame: dict[int, list[tuple[str, Path]]] = {}
    for i, cam, path in paths:
        by_frame.setdefault(i, []).append((cam, path))
    urdf = nominal_urdf(ds)
    names = list(robot.joint_names)
    chain, _ = bag_chain(ds.root, robot)
    frames = camera_frames(ds.info.cameras)
    with BagWriter(out, fmt) as w:
        w.string("/robot_description", start, urdf)
        w.tf("/tf_static", start, static_edges(chain, ds.info.cameras))
        k = 0
        for t in ticks:
            while k < n and int(stamps[k]) < t:
                k += 1
            # frame k is the next image at or after t; frame k - 1 the last one before it
            qt = _joints_at(int(t), stamps, q, k, hold, move)
            w.joint_state(joint_topic, int(t), names, qt)
            w.tf("/tf", int(t), moving_edges(chain, qt))
            if k < n and int(stamps[k]) == t:
                for cam, path in by_frame[int(ds.indices[k])]:
                    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
                    if img is None:
                        raise BagError(f"{path}: not a readable image",
                                       fix="re-acquire or re-import the dataset")  # fmt: skip
                    if img.ndim == 3 and img.shape[2] == 4:
                        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
                    w.image(f"/{cam}/image_raw", int(t), frames[cam], img)
                    w.camera_info(f"/{cam}/camera_info", int(t), frames[cam], infos[cam])
    return BagExport(Path(out), fmt, n, ds.info.cameras, len(ticks), (end - start) / NS)


def _joints_at(
    t: int, stamps: np.ndarray, q: np.ndarray, k: int, hold: int, move: int
) -> np.ndarray:
    """The exported motion at ``t`` (ns): rest within ``hold`` of a frame's stamp, else the
    minimum-jerk move from the previous frame's reading to the next one's."""
    n = len(stamps)
    if k < n and t >= int(stamps[k]) - hold:
        return q[k]
    if k == 0:
        return q[0]
    prev = k - 1
    if k >= n or t <= int(stamps[prev]) + hold:
        return q[prev]
    s = min(max((t - int(stamps[prev]) - hold) / move, 0.0), 1.0)
    return q[prev] + (q[k] - q[prev]) * float(_min_jerk(np.array(s)))
