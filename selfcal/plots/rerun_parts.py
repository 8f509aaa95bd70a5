"""What the Rerun recordings (:mod:`selfcal.plots.rerun_log` for the marker field,
:mod:`selfcal.plots.rerun_board` for a board) log alike: the robot's geometry by shape and a camera
(pose, frustum, image, detected points). ``rerun`` is imported in the functions (~0.6 s)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from selfcal.sim.posed_geometry import PosedGeometry

__all__ = ["EST_COLOR", "GT_COLOR", "archetypes", "log_camera", "open_recording"]

GT_COLOR = (40, 200, 80, 255)
EST_COLOR = (230, 60, 200, 255)


def _quat_xyzw(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R).reshape(-1, 3, 3)).as_quat()


def archetypes(geo: PosedGeometry, ids: list[int]) -> dict[str, object]:
    """Rerun archetypes for the geoms ``ids`` of ``geo`` at its current posture, by shape."""

    import rerun as rr  # optional, ~0.6 s to import: only when recording

    out: dict[str, object] = {}
    for key, g in geo.groups(ids).items():
        quat = _quat_xyzw(g.R)
        size = g.size
        if key == "boxes":
            half = size.copy()
            for k in np.flatnonzero(g.is_plane):
                half[k] = [size[k, 0] or 0.6, size[k, 1] or 0.6, 0.0005]
            out[key] = rr.Boxes3D(
                centers=g.pos, half_sizes=half, quaternions=quat, colors=g.rgba, fill_mode="solid"
            )
        elif key == "cylinders":
            out[key] = rr.Cylinders3D(
                centers=g.pos,
                lengths=2 * size[:, 1],
                radii=size[:, 0],
                quaternions=quat,
                colors=g.rgba,
                fill_mode="solid",
            )
        elif key == "capsules":
            start = g.pos - g.R[:, :, 2] * size[:, 1:2]
            out[key] = rr.Capsules3D(
                translations=start,
                lengths=2 * size[:, 1],
                radii=size[:, 0],
                quaternions=quat,
                colors=g.rgba,
                fill_mode="solid",
            )
        else:
            half = np.where(size > 0, size, size[:, :1])
            out[key] = rr.Ellipsoids3D(
                centers=g.pos, half_sizes=half, quaternions=quat, colors=g.rgba, fill_mode="solid"
            )
    return out


def log_camera(rec, path: str, T_world_cam: np.ndarray, intr, color, image=None, corners=None):
    import rerun as rr  # optional, ~0.6 s to import: only when recording

    rec.log(
        path,
        rr.Transform3D(translation=T_world_cam[:3, 3], mat3x3=T_world_cam[:3, :3]),
    )
    rec.log(
        path,
        rr.Pinhole(
            image_from_camera=intr.K,
            resolution=[intr.width, intr.height],
            camera_xyz=rr.ViewCoordinates.RDF,
            image_plane_distance=0.05,
            color=color,
        ),
    )
    if image is not None:
        rec.log(f"{path}/image", rr.EncodedImage(path=image))
    if corners is not None:
        ids = sorted(corners)
        if ids:
            uv = np.concatenate([corners[i] for i in ids])
            lab = [f"{i}" if k == 0 else None for i in ids for k in range(len(corners[i]))]
            rec.log(
                f"{path}/image/corners",
                rr.Points2D(uv, radii=1.5, colors=(255, 40, 40), labels=[x or "" for x in lab]),
            )


def open_recording(root: Path, rrd: Path | None, spawn: bool, who: str):
    """A ``rerun.RecordingStream`` of the run in ``root`` writing to ``rrd`` and/or a spawned
    viewer, the world frame Z up logged.

    Raises:
        InputError: neither ``rrd`` nor ``spawn`` (``who`` names the caller).
    """
    import rerun as rr  # optional, ~0.6 s to import: only when recording

    from selfcal.errors import InputError

    if rrd is None and not spawn:
        raise InputError(f"{who} needs an .rrd path, spawn=True, or both")
    rec = rr.RecordingStream("scorbot-selfcal", recording_id=str(Path(root).resolve()))
    if spawn:
        rec.spawn(connect=False)  # start the viewer; the sinks below connect to it
    sinks: list[rr.FileSink | rr.GrpcSink] = []
    if rrd is not None:
        rrd.parent.mkdir(parents=True, exist_ok=True)
        sinks.append(rr.FileSink(str(rrd)))
    if spawn:
        sinks.append(rr.GrpcSink())
    rec.set_sinks(*sinks)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    return rec
