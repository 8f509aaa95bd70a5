"""The cameras the field route estimates, from the dataset: one model shared by the rig, or a
:class:`selfcal.camera.CameraSet` (each camera its own model and free parameters), their initial
values (a ROS bag's CameraInfo) and the estimated lenses the images are detected through again.
"""

from __future__ import annotations

from collections.abc import Sequence

from selfcal.calibration.field.self_calibration import SelfCalibrationResult
from selfcal.camera import CameraSet, LensCamera, Pinhole, camera_model, centered_principal_point
from selfcal.io.dataset_info import DatasetInfo

__all__ = ["dataset_camera", "initial_cameras", "lens_cameras", "models_of"]


def dataset_camera(info: DatasetInfo) -> Pinhole | CameraSet:
    """The camera model and free parameters the dataset asks to estimate (values: a centred
    pinhole of the dataset's resolution, no distortion; the self-calibration sets fx, mu): one
    model shared by the rig, or -- when ``dataset.json`` gives the cameras their own models or
    intrinsics (:attr:`selfcal.io.dataset_info.DatasetInfo.own_intrinsics`) -- a
    :class:`selfcal.camera.CameraSet` of each camera's."""
    W, H = info.resolution
    cx, cy = centered_principal_point(W, H)
    names = info.cameras if info.own_intrinsics else info.cameras[:1]
    cams = tuple(camera_model(m, fx=1.0, mu=1.0, cx=cx, cy=cy, width=W, height=H, free=f)
                 for m, f in (info.model_of(c) for c in names))  # fmt: skip
    return cams[0] if len(cams) == 1 else CameraSet(cams, tuple(names))


def models_of(cameras: Pinhole | CameraSet) -> tuple[Pinhole, ...]:
    """The models of ``cameras`` (one for a shared camera)."""
    return cameras.cameras if isinstance(cameras, CameraSet) else (cameras,)  # type: ignore[return-value]


def lens_cameras(sc: SelfCalibrationResult, names: Sequence[str]) -> dict[str, LensCamera]:
    """The estimated cameras with a lens by camera name (every camera for a shared one)."""
    if sc.cameras is None:
        return dict.fromkeys(names, sc.camera) if isinstance(sc.camera, LensCamera) else {}
    return {n: c for n, c in zip(sc.cameras.names, sc.cameras.cameras, strict=True)
            if isinstance(c, LensCamera)}  # fmt: skip


def initial_cameras(info: DatasetInfo, camera: Pinhole | CameraSet) -> Pinhole | CameraSet | None:
    """The dataset's initial camera(s) (a ROS bag's CameraInfo): each camera's own when every
    camera of a set has one, else the first camera's (for every camera), or None."""
    first = info.initial_camera(info.cameras[0])
    if isinstance(camera, CameraSet):
        own = tuple(info.initial_camera(n) for n in camera.names)
        if all(c is not None for c in own):
            return CameraSet(own, camera.names)  # type: ignore[arg-type]
    return first
