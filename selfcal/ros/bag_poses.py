"""``selfcal import --bag BAG --tf-parent BASE --tf-child FLANGE --setup SETUP``: a ROS bag's
images and the flange poses its ``/tf`` records, as a pose dataset (no joints, no robot model).

Two streaming passes over the bag, as the joint import (:mod:`selfcal.ros.bag_import`):

1. ``/tf_static`` and ``/tf`` (:class:`selfcal.ros.tf_track.TfSeries`): the pose of
   ``--tf-child`` in ``--tf-parent`` at any stamp, and when it rested;
2. the camera's image topic: an image taken at rest (the same rest test as for joints, on the
   pose: :class:`selfcal.ros.bag_rest.RestRule`'s mm/s and deg/s) is decoded and staged, any
   other counted.

At most ``--per-rest`` images of each rest are kept (default 1, the middle one), their poses
looked up at the image stamps (header stamps), and :func:`selfcal.importing.poses.import_pose_dataset`
checks and writes the dataset exactly as for image files and a pose file. ``dataset.json``
records the bag, the topic, the frame pair and the rest rule (``provenance.import``),
``sources.csv`` each image's ``BAG#TOPIC@STAMP_NS``.
"""

from __future__ import annotations

import csv
import io
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.choices import DEFAULT_MODEL, SETUPS
from selfcal.importing.dataset import CameraImages, ImportError_
from selfcal.importing.poses import import_pose_dataset
from selfcal.io.atomic import write_text_atomic
from selfcal.io.poses.dataset import PoseDataset
from selfcal.ros.bag_import import ImageTopic
from selfcal.ros.bag_rest import GAP, MOVING, OUTSIDE, RestRule, pair_frames, thin_rests
from selfcal.ros.bag_stage import name_frames, stage_images, warn_skipped
from selfcal.ros.rosbag import IMAGE_TYPES, BagError, BagReader
from selfcal.ros.tf_track import TfSeries

__all__ = ["import_bag_poses"]

_TF = ("/tf_static", "/tf")


def import_bag_poses(
    bag: str | Path | Sequence[str | Path],
    image_topic: ImageTopic,
    tf_parent: str,
    tf_child: str,
    target: str | Path,
    out: str | Path,
    setup: str,
    *,
    rule: RestRule | None = None,
    per_rest: int | None = 1,
    camera_model: str | None = None,
    free: Sequence[str] | None = None,
) -> PoseDataset:
    """Import the bag ``bag`` (a path, or the files of a split ROS 1 recording) as the pose
    dataset ``out`` (module docstring); returns it. ``tf_parent`` -> ``tf_child``: the robot's
    base and flange (or tool) frames; ``setup``: eye-in-hand or eye-to-hand; ``rule``, ``per_rest``:
    as :func:`selfcal.ros.bag_import.import_bag`; ``camera_model``, ``free``: as
    :func:`selfcal.importing.poses.import_pose_dataset`.

    Raises:
        selfcal.ros.rosbag.BagError: a missing topic, no transforms, frames /tf does not join or
            that never move, no image at rest (each names the bag, the topic or frame and the
            fix); the errors of ``import_pose_dataset``.
    """
    if setup not in SETUPS:
        raise ImportError_(f"--setup {setup!r}", fix=f"use one of {', '.join(SETUPS)}")
    bags = [Path(bag)] if isinstance(bag, (str, Path)) else [Path(b) for b in bag]
    out = Path(out)
    rule = RestRule() if rule is None else rule
    if (out / "dataset.json").exists():
        raise ImportError_(f"{out} already holds a dataset", fix="choose another --out folder")
    where_dir = out.parent if out.parent.is_dir() else None
    with tempfile.TemporaryDirectory(prefix=".selfcal-bag-", dir=where_dir) as tmp:
        stage = Path(tmp)
        with BagReader(bags) as reader:
            where, fmt = reader.label, reader.format
            reader.require(image_topic.topic, IMAGE_TYPES, "--image-topic")
            tf_topics = [t for t in _TF if t in reader.topics]
            if not tf_topics:
                raise BagError(f"{where}: no /tf or /tf_static topic: the flange poses of "
                               f"{tf_parent} -> {tf_child} are not in the bag",
                               fix="record /tf and /tf_static with the images, or import the "
                               "joints with --robot and --joint-topic")  # fmt: skip
            series = TfSeries(where)
            for t, _m, msg, stamp in reader.timed(tf_topics):
                series.add(msg, static=t == "/tf_static", stamp=stamp)
            track = series.track(tf_parent, tf_child)
            staged, counts, total, span, _ids = stage_images(
                reader, {image_topic.name: image_topic.topic}, track, rule, "/tf", stage)  # fmt: skip
        name = image_topic.name
        at_rest = len(staged[name].files)
        if at_rest == 0:
            raise BagError(
                f"{where}: none of the {total} images on {image_topic.topic} was taken at rest "
                f"of {tf_parent} -> {tf_child} ({counts[MOVING]} while moving, {counts[GAP]} at a "
                f"pause of /tf, {counts[OUTSIDE]} outside its recording; rest test: "
                f"{rule.describe()}, {rule.speed_m_s * 1e3:g} mm/s)",
                fix="record stop-and-go motion that rests at least 1 s at every posture "
                "(docs/ros.md), or loosen --rest-speed / shorten --rest-window",
            )
        frames = pair_frames({name: staged[name].stamps}, [name], track, rule)
        frames = thin_rests(frames, staged[name].stamps, track, rule, per_rest)
        warn_skipped(where, rule, counts, total, at_rest, frames, 1, motion="the /tf")
        files = name_frames(staged, [name], frames, stage)[name]
        stamps = np.array([staged[name].stamps[f[0]] for f in frames], np.int64)
        T = series.lookup(tf_parent, tf_child, stamps)
        q = Rotation.from_matrix(T[:, :3, :3]).as_quat()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["image", "x_mm", "y_mm", "z_mm", "qx", "qy", "qz", "qw"])
        for f, Tk, qk in zip(files, T, q, strict=True):
            w.writerow([f.name] + [repr(float(v)) for v in Tk[:3, 3] * 1e3]
                       + [repr(float(v)) for v in qk])  # fmt: skip
        poses = stage / "poses.csv"
        write_text_atomic(poses, buf.getvalue())
        labels = {f: f"{staged[name].bags[fr[0]].resolve()}#{image_topic.topic}@{int(s)}"
                  for f, fr, s in zip(files, frames, stamps)}  # fmt: skip
        source = {
            "bag": str(bags[0].resolve()) if len(bags) == 1 else [str(b.resolve()) for b in bags],
            "format": fmt, "image_topic": image_topic.topic,
            "tf": {"parent": tf_parent, "child": tf_child, "messages": series.messages},
            "rest": rule.to_json(), "target": str(target),
            "images": {"total": total, "at_rest": at_rest, "frames": len(frames), **counts},
        }  # fmt: skip
        return import_pose_dataset(
            CameraImages(name, image_topic.topic, tuple(files)), poses, target, out, setup,
            rotation="quaternion-xyzw", units="mm", camera_model=camera_model or DEFAULT_MODEL,
            free=free, source=source, labels=labels,
        )  # fmt: skip
