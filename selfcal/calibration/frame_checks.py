"""Frames that must not be calibrated together, or whose joints do not belong to them (#15).

Two frames of one dataset are never alike: every posture is taken once, and the camera noise
alone moves a corner by a tenth of a pixel between two images of one posture. So two frames whose
marker corners agree (the same markers in every camera, corners within :data:`NEAR_PX`), or whose
joint readings are equal to the last digit, are a copy of one frame, a camera that delivered an
old image, or a joint read-back that did not change. Before this check a copied frame cost a
full calibration and then failed with an error naming no frame (or, on the analytic path, was
weighted twice without a word).

A frame's joint read-back rests within the encoder resolution of its planned posture; one far
from it (:data:`READBACK_DEG`) is a joints row of another frame, joints in radians where
``joints.csv`` declares degrees (before: an IdentificationError), or a robot that stopped short.
"""

from __future__ import annotations

import re

import numpy as np

from selfcal.errors import SelfCalWarning
from selfcal.io.dataset import DatasetError, Detections

__all__ = [
    "NEAR_PX",
    "READBACK_DEG",
    "alike_frames",
    "check_distinct_frames",
    "check_read_back",
    "unused_frames_message",
    "UnusedFramesWarning",
]

NEAR_PX = 0.05
"""Largest RMS difference (px) of the corners of two frames that counts as the same image. Two
postures of a 30-pose default-scenario dataset differ by at least 54 px RMS over the markers they
both see (analytic path, scenarios/paper.toml with render = false); a copied frame by 0."""


def _signature(dets: Detections, index: int, cameras: tuple[str, ...]):
    """(the markers seen, by camera) and the corners (flat, px) of frame ``index``."""
    keys = tuple((c, m) for c in cameras for m in sorted(dets.get((index, c), {})))
    if not keys:
        return keys, np.zeros(0)
    return keys, np.concatenate([dets[(index, c)][m].reshape(-1) for c, m in keys])


def alike_frames(
    indices: np.ndarray, joints_deg: np.ndarray, dets: Detections, cameras: tuple[str, ...]
) -> list[str]:
    """One sentence per pair of frames (by index) that are alike: the same corners (RMS
    difference at most :data:`NEAR_PX` px over the same markers in every camera) or the same
    joint readings (deg, equal to the file's last digit)."""
    out: list[str] = []
    idx = [int(i) for i in indices]
    q = np.asarray(joints_deg, dtype=float)
    groups: dict[tuple, list[int]] = {}
    corners = {}
    for k, i in enumerate(idx):
        keys, c = _signature(dets, i, cameras)
        corners[k] = c
        if keys:
            groups.setdefault(keys, []).append(k)
    same_images: set[tuple[int, int]] = set()
    for members in groups.values():
        if len(members) < 2:
            continue
        C = np.stack([corners[k] for k in members])
        d = np.sqrt(np.mean((C[:, None, :] - C[None, :, :]) ** 2, axis=2))
        for a, b in zip(*np.nonzero(np.triu(d <= NEAR_PX, k=1))):
            ka, kb = members[a], members[b]
            same_images.add((ka, kb))
            dq = float(np.max(np.abs(q[ka] - q[kb])))
            how = "identical" if d[a, b] == 0.0 else f"within {d[a, b]:.3f} px RMS"
            if dq == 0.0:
                why = f"and the same joint readings: frame {idx[kb]} is a copy of frame {idx[ka]}"
            else:
                why = (
                    f"although their joint readings differ by up to {dq:.3g} deg: a camera "
                    "delivered an old image, or an image file was copied"
                )
            out.append(f"frames {idx[ka]} and {idx[kb]} show the same corners ({how}) {why}")
    out += _cameras_alike(idx, dets, cameras)
    for a in range(len(idx)):
        for b in np.flatnonzero(np.all(q[a + 1 :] == q[a], axis=1)) + a + 1:
            if (a, int(b)) not in same_images:
                out.append(
                    f"frames {idx[a]} and {idx[b]} have the same joint readings but different "
                    "images: a joints.csv row was copied, or the joint read-back did not change "
                    "while the robot moved"
                )
    return out


def _cameras_alike(idx: list[int], dets: Detections, cameras: tuple[str, ...]) -> list[str]:
    """One sentence per frame in which two cameras show the same corners (within
    :data:`NEAR_PX`): the cameras of a rig look from other places, so one image is a copy of the
    other (before: the frame dropped without a word, or an outlier-rejection error naming none)."""
    out = []
    for i in idx:
        for a, ca in enumerate(cameras):
            for cb in cameras[a + 1 :]:
                da, db = dets.get((i, ca), {}), dets.get((i, cb), {})
                if not da or sorted(da) != sorted(db):
                    continue
                d = np.sqrt(np.mean([np.mean((da[m] - db[m]) ** 2) for m in da]))
                if d <= NEAR_PX:
                    how = "identical" if d == 0.0 else f"within {d:.3f} px RMS"
                    out.append(
                        f"frame {i}: the {cb} image shows the same corners as the {ca} image "
                        f"({how}): one camera's image was copied over the other's"
                    )
    return out


class UnusedFramesWarning(SelfCalWarning):
    """Frames the calibration could not use are left out (named; also in the result)."""


def unused_frames_message(indices: np.ndarray, used: np.ndarray, skipped: tuple[str, ...]) -> str:
    """The sentence naming the frames (by index) of ``indices`` not among the positions ``used``
    (a warning and in ``calibration.json``), or ``""`` when every frame is used; ``skipped``:
    the images without markers (``NNNN_camera``), named with their frame."""
    kept = {int(u) for u in used}
    unused = [int(i) for k, i in enumerate(indices) if k not in kept]
    if not unused:
        return ""
    empty = {int(m[0]) for m in (re.match(r"[0-9]{1,9}", n) for n in skipped) if m}
    named = [f"{i} (an image without markers)" if i in empty else str(i) for i in unused]
    return (
        f"{len(unused)} of {len(indices)} frame(s) not used by the calibration: "
        f"{', '.join(named[:20])}{' ...' if len(named) > 20 else ''}; the camera stage could not "
        "register them with the others (too few markers shared with other frames, or images "
        "that do not agree with them: an image of another frame or camera)"
    )


def check_distinct_frames(
    indices: np.ndarray,
    joints_deg: np.ndarray,
    dets: Detections,
    cameras: tuple[str, ...],
    where: str,
) -> None:
    """Raise a :class:`selfcal.io.dataset.DatasetError` naming every pair of alike frames
    (:func:`alike_frames`) of the dataset ``where``; nothing when there is none."""
    pairs = alike_frames(indices, joints_deg, dets, cameras)
    if not pairs:
        return
    more = f"\n  ... ({len(pairs)} pairs in all)" if len(pairs) > 10 else ""
    raise DatasetError(
        f"{where}: {len(pairs)} pair(s) of frames are alike (each posture is taken once):"
        + "".join(f"\n  - {p}" for p in pairs[:10])
        + more,
        fix="remove the copied frames' rows from joints.csv (and calibrate with "
        "--allow-missing-frames), or re-acquire them",
    )


READBACK_DEG = 5.0
"""Largest difference (deg, or mm for a prismatic joint) between a frame's joint read-back and
its planned posture that is accepted. The read-back rests within the encoder resolution of the
target (0.0072 deg for the ER-4u's base, tests/integration/test_hardware_e2e.py); an imported
dataset plans exactly what it read."""


def check_read_back(
    indices: np.ndarray, joints_deg: np.ndarray, planned_deg: np.ndarray, where: str
) -> None:
    """Raise a :class:`selfcal.io.dataset.DatasetError` when frames read joints more than
    :data:`READBACK_DEG` away from their planned postures (``indices`` into ``planned_deg``):
    joints in radians where ``joints.csv`` declares degrees, rows or columns out of order, a
    robot that did not reach the posture. Frames outside the plan are not checked."""
    idx = np.asarray(indices, dtype=int)
    ok = (idx >= 0) & (idx < len(planned_deg))
    if not ok.any() or np.shape(planned_deg)[1:] != np.shape(joints_deg)[1:]:
        return
    q, plan = np.asarray(joints_deg, dtype=float)[ok], np.asarray(planned_deg, dtype=float)[idx[ok]]
    dev = np.abs(q - plan).max(axis=1)
    far = np.flatnonzero(dev > READBACK_DEG)
    if not len(far):
        return
    k = int(far[np.argmax(dev[far])])
    j = int(np.argmax(np.abs(q[k] - plan[k])))
    example = (f"frame {idx[ok][k]}: q{j + 1}_deg = {q[k, j]:.4f} read, {plan[k, j]:.4f} "
               "planned")  # fmt: skip
    if len(far) == len(q) and np.abs(np.degrees(q) - plan).max() <= READBACK_DEG:
        raise DatasetError(
            f"{where}: the joint readings look like radians: every frame is within "
            f"{READBACK_DEG:g} deg of its planned posture once read as radians, none as "
            f"degrees ({example})",
            fix="write joints.csv in degrees (its columns are qN_deg), e.g. re-import with "
            "--joint-units rad",
        )
    frames = ", ".join(str(i) for i in idx[ok][far][:20]) + (" ..." if len(far) > 20 else "")
    raise DatasetError(
        f"{where}: {len(far)} frame(s) read joints more than {READBACK_DEG:g} deg from their "
        f"planned postures (frames {frames}; worst {example}): the rows do not belong to "
        "these frames (rows or columns out of order), or the robot did not reach the posture",
        fix="restore joints.csv as acquired, or re-acquire those frames",
    )
