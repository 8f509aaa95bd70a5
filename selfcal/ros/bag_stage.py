"""Staging a bag's images at rest, shared by the joint import (:mod:`selfcal.ros.bag_import`)
and the /tf pose import (:mod:`selfcal.ros.bag_poses`): each image taken at rest decoded and
written as a PNG at once (memory does not grow with the bag), the others counted by reason
and reported in one warning line, the frames kept renamed ``NNNNNN.png``.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2

from selfcal.errors import SelfCalWarning
from selfcal.importing.dataset import ImportError_
from selfcal.ros.bag_rest import EMPTY, GAP, MOVING, NS, OUTSIDE, REST, JointTrack, RestRule
from selfcal.ros.rosbag import BagError, BagReader, decode_image

__all__ = [
    "MovingImagesWarning",
    "Staged",
    "name_frames",
    "secs",
    "stage_images",
    "warn_skipped",
]


class MovingImagesWarning(SelfCalWarning):
    """Images of the bag skipped because the arm moved (or the joint messages do not cover them);
    counted in one line."""


def secs(t: int) -> str:
    """A stamp ``t`` (integer ns) as seconds for a message."""
    return f"{t / NS:.3f} s"


@dataclass
class Staged:
    """The images at rest of one camera: stamps (ns) and staged files."""

    stamps: list[int]
    files: list[Path]
    bags: list[Path]


def stage_images(
    reader: BagReader, cameras: Mapping[str, str], track: JointTrack, rule: RestRule,
    joint_topic: str, stage: Path,
) -> tuple[dict[str, Staged], dict[str, int], int, tuple[int, int], dict[str, str]]:  # fmt: skip
    """The image pass of a bag import: decode every image of ``cameras`` (camera name -> image
    topic) taken at rest of ``track`` (by ``rule``; ``joint_topic`` names the motion's topic in
    messages) and stage it as a PNG under ``stage/NAME/``; count the others by reason. Returns
    the staged images per camera, the counts (``MOVING``, ``GAP``, ``OUTSIDE``), the number of
    images, the first and last image stamps (ns) and each camera's frame_id (of its first
    image).

    Raises:
        BagError: no motion message within the rest window of an image; an image encoding
            that cannot be decoded.
    """
    by_topic = {topic: name for name, topic in cameras.items()}
    staged = {name: Staged([], [], []) for name in cameras}
    for name in cameras:
        (stage / name).mkdir(parents=True)
    counts = {MOVING: 0, GAP: 0, OUTSIDE: 0}
    total, first, last = 0, 2**63 - 1, -(2**63)
    frame_ids: dict[str, str] = {}
    for topic, msgtype, msg, t, src in reader.timed_in(list(by_topic)):
        total += 1
        frame_ids.setdefault(by_topic[topic], str(msg.header.frame_id))
        first, last = min(first, t), max(last, t)
        st = track.status(t, rule)
        if st == EMPTY:
            a, b = track.largest_gap(t)
            raise BagError(
                f"{reader.label}: no message on {joint_topic} within +-{rule.window_s / 2:g} s of "
                f"the image at {secs(t)} on {topic} (the joint messages pause from {a:.3f} s to "
                f"{b:.3f} s)",
                fix="record the joint topic without pauses (check the driver's publish rate and "
                "dropped messages), or give the --joint-topic the driver publishes continuously",
            )
        if st != REST:
            counts[st] += 1
            continue
        s = staged[by_topic[topic]]
        img = decode_image(msg, msgtype, f"{src}: topic {topic}")
        path = stage / by_topic[topic] / f"raw_{len(s.files):07d}.png"
        if not cv2.imwrite(str(path), img):  # pragma: no cover
            raise ImportError_(f"{path}: cannot write the staged image", fix="check the disk")
        s.stamps.append(t)
        s.files.append(path)
        s.bags.append(src)
    return staged, counts, total, (first, last), frame_ids


def name_frames(
    staged: dict[str, Staged], names: Sequence[str], frames: list[list[int]], stage: Path
) -> dict[str, list[Path]]:
    """Rename each frame's staged images to ``NNNNNN.png`` (one name across the cameras, the
    joints file's image column) and delete the unused ones."""
    out: dict[str, list[Path]] = {n: [] for n in names}
    for k, f in enumerate(frames):
        for n, i in zip(names, f):
            dst = stage / n / f"{k:06d}.png"
            os.replace(staged[n].files[i], dst)
            out[n].append(dst)
    for n in names:
        for p in (stage / n).glob("raw_*.png"):
            p.unlink()
    return out


def warn_skipped(bag: str, rule: RestRule, counts: dict[str, int], total: int, at_rest: int,
                  frames: list[list[int]], n_cams: int,
                  motion: str = "the joint") -> None:  # fmt: skip
    """The warning for the images not kept; ``motion`` names what tells the motion (the joint
    messages, or /tf's)."""
    skipped = total - at_rest
    unpaired = at_rest - len(frames) * n_cams
    if not skipped and not unpaired:
        return
    parts = [f"{counts[MOVING]} with the arm moving within +-{rule.window_s / 2:g} s"]
    if counts[GAP]:
        parts.append(f"{counts[GAP]} at a pause of {motion} messages")
    if counts[OUTSIDE]:
        parts.append(f"{counts[OUTSIDE]} outside {motion} recording")
    if unpaired:
        parts.append(f"{unpaired} at rest but not in a frame (no image of every camera in that "
                     "rest, or beyond --per-rest)")  # fmt: skip
    warnings.warn(
        f"{bag}: {skipped + unpaired} of {total} images skipped: {', '.join(parts)}; "
        f"{len(frames)} frame(s) at rest kept",
        MovingImagesWarning,
        stacklevel=3,
    )
