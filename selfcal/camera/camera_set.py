"""The cameras of a rig as one estimation unknown: each camera its own model and free parameters.

A field self-calibration of a rig whose cameras differ (other lenses, other free parameters)
estimates one intrinsics block per camera. :class:`CameraSet` concatenates the cameras' free
parameters into one vector (camera 0's first, in its ``free`` order, then camera 1's ...), so
the estimation's one ``intrinsics`` parameter block holds all of them, and projects each
observation row with the camera of its view (``view = frame * N + camera``,
:class:`selfcal.estimation.observations.ViewLayout`). A rig whose cameras share one model is estimated with
that one :class:`selfcal.camera.CameraModel` instead (the paper's setting), never with a set.

:func:`project_views`, :func:`unproject_views` and :func:`project_free_views` take either kind
(``Cameras``), so the code of the estimation is written once for both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.camera.model import CameraModel
from selfcal.errors import InputError, UsageError

__all__ = [
    "CameraSet",
    "Cameras",
    "project_views",
    "unproject_views",
    "project_free_views",
    "first_camera",
    "free_std",
    "std_by_name",
]


@dataclass(frozen=True)
class CameraSet:
    """``cameras`` (N models, camera c of the rig is ``cameras[c]``) and their ``names`` (N).

    ``free`` qualifies every free parameter with its camera's name (``"right.k1"``) in the
    order of :meth:`free_values`.

    Raises ``ValueError`` for fewer than two cameras or a names count that differs.
    """

    cameras: tuple[CameraModel, ...]
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        cams, names = tuple(self.cameras), tuple(self.names)
        if len(cams) < 2 or len(names) != len(cams) or len(set(names)) != len(names):
            raise InputError(
                f"a camera set needs N >= 2 cameras and N distinct names; got {len(cams)} "
                f"cameras, names {names} (one camera, or one model shared by the rig: use the "
                "CameraModel itself)"
            )
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "names", names)

    @property
    def n_cameras(self) -> int:
        """N."""
        return len(self.cameras)

    @property
    def n_free(self) -> int:
        """How many parameters the estimation adjusts, over every camera."""
        return sum(c.n_free for c in self.cameras)

    @property
    def free(self) -> tuple[str, ...]:
        """Every free parameter as ``"<camera>.<name>"``, in :meth:`free_values` order."""
        return tuple(f"{n}.{p}" for n, c in zip(self.names, self.cameras, strict=True)
                     for p in c.free)  # fmt: skip

    def slices(self) -> tuple[slice, ...]:
        """Each camera's part of the free vector."""
        ends = np.cumsum([0] + [c.n_free for c in self.cameras])
        return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:], strict=True))

    def free_values(self) -> np.ndarray:
        """The free parameters' values (n_free,), camera after camera."""
        return np.concatenate([c.free_values() for c in self.cameras])

    def with_free_values(self, free_values: np.ndarray) -> CameraSet:
        """The same cameras with their free parameters set to ``free_values`` (n_free,)."""
        v = np.asarray(free_values, dtype=float).reshape(-1)
        if len(v) != self.n_free:
            raise UsageError(f"{len(v)} values for {self.n_free} free camera parameters")
        cams = tuple(
            c.with_free_values(v[s]) for c, s in zip(self.cameras, self.slices(), strict=True)
        )
        return CameraSet(cams, self.names)

    def camera_of_view(self, view: np.ndarray) -> np.ndarray:
        """The camera index of each view (``view = frame * N + camera``)."""
        return np.asarray(view, dtype=np.int64) % self.n_cameras

    def std_by_camera(self, cov: np.ndarray) -> dict[str, dict[str, float]]:
        """Standard deviations of each camera's free parameters by camera name and parameter
        name, from the covariance ``cov`` (n_free, n_free) in :meth:`free_values` order."""
        return {
            n: std_by_name(c, cov[s, s])
            for n, c, s in zip(self.names, self.cameras, self.slices(), strict=True)
        }


Cameras = CameraModel | CameraSet
"""What the estimation adjusts: one model shared by every camera of the rig, or a set."""


def first_camera(cameras: Cameras) -> CameraModel:
    """The first camera's model (the shared one for a :class:`CameraModel`)."""
    return cameras.cameras[0] if isinstance(cameras, CameraSet) else cameras


def free_std(
    cameras: Cameras, cov: np.ndarray
) -> tuple[dict[str, float], dict[str, dict[str, float]] | None]:
    """Standard deviations from the covariance ``cov`` (n, n) of ``cameras``' free parameters:
    the first camera's by parameter name, and every camera's by camera name (None for one
    shared model)."""
    if isinstance(cameras, CameraSet):
        per = cameras.std_by_camera(cov)
        return per[cameras.names[0]], per
    return std_by_name(cameras, cov), None


def std_by_name(camera: CameraModel, cov: np.ndarray) -> dict[str, float]:
    """Standard deviations of ``camera``'s free parameters by name from their covariance
    ``cov``; with ``fx`` free also OpenCV's ``fy = mu fx`` (first order: ``var fy = mu^2 var fx
    + fx^2 var mu + 2 fx mu cov(fx, mu)``, ``mu std(fx)`` with ``mu`` held), so a file read by
    OpenCV's names has every one's."""
    free = list(camera.free)
    out = dict(zip(free, (float(v) for v in np.sqrt(np.clip(np.diag(cov), 0.0, None))),
                   strict=True))  # fmt: skip
    values = dict(zip(camera.names, camera.values().tolist(), strict=True))
    fx, mu = float(values["fx"]), float(values["mu"])
    if "fx" in free and "mu" in free:
        i, j = free.index("fx"), free.index("mu")
        var = mu**2 * cov[i, i] + fx**2 * cov[j, j] + 2.0 * fx * mu * cov[i, j]
        out["fy"] = float(np.sqrt(max(var, 0.0)))
    elif "fx" in free:  # mu held: fy moves with fx
        out["fy"] = abs(mu) * out["fx"]
    return out


def project_views(cameras: Cameras, X_cam: np.ndarray, view: np.ndarray) -> np.ndarray:
    """Pixels (..., k, 2) of camera-frame points ``X_cam`` (..., k, 3) (m) of the rows seen in
    views ``view`` (k,), each with its camera's model."""
    if not isinstance(cameras, CameraSet):
        return cameras.project(X_cam)
    X = np.asarray(X_cam, dtype=float)
    out = np.empty(X.shape[:-1] + (2,))
    cam = cameras.camera_of_view(view)
    for c, model in enumerate(cameras.cameras):
        m = cam == c
        out[..., m, :] = model.project(X[..., m, :])
    return out


def unproject_views(cameras: Cameras, uv: np.ndarray, view: np.ndarray) -> np.ndarray:
    """Normalised coordinates (k, 2) of the pixels ``uv`` (k, 2) seen in views ``view`` (k,)."""
    if not isinstance(cameras, CameraSet):
        return cameras.unproject_normalised(uv)
    out = np.empty(np.shape(uv))
    cam = cameras.camera_of_view(view)
    for c, model in enumerate(cameras.cameras):
        m = cam == c
        out[m] = model.unproject_normalised(np.asarray(uv)[m])
    return out


def project_free_views(
    cameras: Cameras, X_cam: np.ndarray, view: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels (k, 2), the Jacobian w.r.t. the camera-frame point (k, 2, 3) px/m and w.r.t. the
    free parameters (k, 2, n_free) of rows ``X_cam`` (k, 3) seen in views ``view`` (k,); a
    row's derivatives w.r.t. another camera's parameters are zero."""
    if not isinstance(cameras, CameraSet):
        return cameras.project_free(X_cam)
    k = len(X_cam)
    uv, A = np.empty((k, 2)), np.empty((k, 2, 3))
    J = np.zeros((k, 2, cameras.n_free))
    cam = cameras.camera_of_view(view)
    for c, (model, s) in enumerate(zip(cameras.cameras, cameras.slices(), strict=True)):
        m = cam == c
        uv[m], A[m], J[m, :, s] = model.project_free(X_cam[m])
    return uv, A, J
