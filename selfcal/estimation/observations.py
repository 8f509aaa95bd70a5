"""Image measurements: target features seen per frame and camera, with the indexing in one place.

A *frame* (also called a configuration: one robot posture) is photographed by the ``N`` cameras
of the rig; each (frame, camera) image is a *view*. :class:`ViewLayout` is the one place of the
view arithmetic -- ``view = frame * N + camera`` and its inverses, the (V, ...) <-> (m, N, ...)
reshapes, the views of one camera or one frame -- so that no other module writes ``2 * config +
camera``. :class:`Observations` holds one row per (view, feature): frame, camera, feature id and
pixel coordinates (px, OpenCV convention: x right, y down, pixel centres at integers).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.camera import STEREO_NAMES
from selfcal.errors import InputError, UsageError
from selfcal.target import Features, markers_to_features

__all__ = ["ViewLayout", "Observations", "RowGroups", "views_per_point"]


@dataclass(frozen=True)
class ViewLayout:
    """Views of ``n_frames`` frames by ``n_cameras`` cameras: ``view = frame * n_cameras +
    camera``. Arrays over views (V, ...) list the cameras of frame 0, then of frame 1, ..."""

    n_frames: int
    n_cameras: int = 2

    @property
    def n_views(self) -> int:
        """V = frames x cameras."""
        return self.n_frames * self.n_cameras

    def view(self, frame: np.ndarray | int, camera: np.ndarray | int) -> np.ndarray:
        """View index of (frame, camera) (broadcast)."""
        return np.asarray(frame) * self.n_cameras + np.asarray(camera)

    def frame(self, view: np.ndarray | int) -> np.ndarray:
        """Frame of each view."""
        return np.asarray(view) // self.n_cameras

    def camera(self, view: np.ndarray | int) -> np.ndarray:
        """Camera of each view."""
        return np.asarray(view) % self.n_cameras

    def by_frame(self, a: np.ndarray) -> np.ndarray:
        """(V, ...) -> (m, N, ...) (a view of ``a`` where numpy can)."""
        a = np.asarray(a)
        return a.reshape((self.n_frames, self.n_cameras) + a.shape[1:])

    def by_view(self, a: np.ndarray) -> np.ndarray:
        """(m, N, ...) -> (V, ...)."""
        a = np.asarray(a)
        return a.reshape((self.n_views,) + a.shape[2:])

    def of_camera(self, a: np.ndarray, camera: int) -> np.ndarray:
        """The entries (m, ...) of camera ``camera`` in an array over views (V, ...) (a numpy
        view: assignments write through)."""
        return np.asarray(a)[camera :: self.n_cameras]

    def frame_any(self, per_view: np.ndarray) -> np.ndarray:
        """(m,) bool: some camera of the frame has ``per_view`` (V,) set."""
        return np.asarray(self.by_frame(per_view).any(axis=1))

    def frame_all(self, per_view: np.ndarray) -> np.ndarray:
        """(m,) bool: every camera of the frame has ``per_view`` (V,) set."""
        return np.asarray(self.by_frame(per_view).all(axis=1))

    def per_view(self, per_frame: np.ndarray) -> np.ndarray:
        """(V, ...) each frame's entry repeated for its cameras, from ``per_frame`` (m, ...)."""
        return np.repeat(np.asarray(per_frame), self.n_cameras, axis=0)

    def same_frame(self, view_a: np.ndarray | int, view_b: np.ndarray | int) -> np.ndarray:
        """Whether two views are images of one frame (by different cameras or the same)."""
        return self.frame(view_a) == self.frame(view_b)


class RowGroups:
    """Observation rows grouped by a key in ``0..n-1`` (a view, a point index), sorted once, so
    that the rows of a few keys are found without scanning every row.

    ``key`` (k,) int; the rows of each key come out in ascending row order (as
    ``np.flatnonzero(key == g)`` gives them)."""

    def __init__(self, key: np.ndarray, n: int) -> None:
        key = np.asarray(key, dtype=np.int64)
        self.order = np.argsort(key, kind="stable")
        self.bounds = np.concatenate([[0], np.cumsum(np.bincount(key, minlength=n))])

    def rows_of_one(self, g: int) -> np.ndarray:
        """The rows whose key is ``g``, ascending."""
        return self.order[self.bounds[g] : self.bounds[g + 1]]

    def rows_of(self, keys: np.ndarray) -> np.ndarray:
        """The rows whose key is one of ``keys`` (distinct), ascending (as
        ``np.flatnonzero(np.isin(key, keys))``)."""
        keys = np.asarray(keys, dtype=np.int64)
        start, n = self.bounds[keys], self.bounds[keys + 1] - self.bounds[keys]
        at = np.repeat(start - (np.cumsum(n) - n), n) + np.arange(int(n.sum()))
        return np.sort(self.order[at])


def views_per_point(view: np.ndarray, pidx: np.ndarray, n_points: int) -> np.ndarray:
    """(n_points,) how many distinct views see each point, from observation rows ``(view,
    pidx)`` (a point seen twice in one view counts once)."""
    view = np.asarray(view, dtype=np.int64)
    pidx = np.asarray(pidx, dtype=np.int64)
    n_v = int(view.max()) + 1 if len(view) else 1
    if n_points * n_v <= SEEN_TABLE_MAX:  # a table of (point, view) seen: no sort of the rows
        seen = np.zeros((n_points, n_v), bool)
        seen[pidx, view] = True
        return np.count_nonzero(seen, axis=1)
    key = np.unique(pidx * n_v + view)
    return np.bincount(key // n_v, minlength=n_points)


SEEN_TABLE_MAX = 1 << 25
"""Above this many (point, view) pairs :func:`views_per_point` sorts the rows' keys instead of
filling a table of them (32 MB)."""


@dataclass(frozen=True)
class Observations:
    """Image observations of target features, one row per (view, feature).

    ``config`` (k,) int frame index in ``0..n_configs-1``; ``camera`` (k,) int in
    ``0..n_cameras-1`` (0 = left, 1 = right for the stereo pair); ``point`` (k,) int feature id
    (:mod:`selfcal.target`); ``uv`` (k, 2) float px (OpenCV). Views: :attr:`layout`.

    Raises ``ValueError`` for arrays of different lengths, indices out of range, negative ids,
    NaN/inf pixels or a feature seen twice in one view.
    """

    config: np.ndarray
    camera: np.ndarray
    point: np.ndarray
    uv: np.ndarray
    n_configs: int
    n_cameras: int = 2

    def __post_init__(self) -> None:
        cfg = np.asarray(self.config, dtype=np.int64).reshape(-1)
        cam = np.asarray(self.camera, dtype=np.int64).reshape(-1)
        pt = np.asarray(self.point, dtype=np.int64).reshape(-1)
        uv = np.asarray(self.uv, dtype=float).reshape(-1, 2)
        k = len(cfg)
        if not (len(cam) == len(pt) == len(uv) == k):
            raise UsageError(
                f"Observations arrays differ in length: config {k}, camera {len(cam)}, "
                f"point {len(pt)}, uv {len(uv)}; give one row per observation"
            )
        if k and (cfg.min() < 0 or cfg.max() >= self.n_configs):
            raise UsageError(f"config indices must lie in 0..{self.n_configs - 1}")
        if k and (cam.min() < 0 or cam.max() >= self.n_cameras):
            raise UsageError(f"camera indices must lie in 0..{self.n_cameras - 1}")
        if k and pt.min() < 0:
            raise UsageError("feature ids must be >= 0 (see selfcal.target)")
        if not np.isfinite(uv).all():
            raise UsageError("uv contains NaN/inf; drop undetected corners instead")
        key = self.layout.view(cfg, cam) * (int(pt.max()) + 1 if k else 1) + pt
        if len(np.unique(key)) != k:
            raise UsageError("a point is observed twice in the same view; deduplicate detections")
        for name, val in (("config", cfg), ("camera", cam), ("point", pt), ("uv", uv)):
            val.setflags(write=False)
            object.__setattr__(self, name, val)

    # ------------------------------------------------------------------------ construction
    @classmethod
    def from_features(
        cls,
        features: Mapping[tuple[int, int | str], Features],
        n_configs: int | None = None,
        cameras: Sequence[str] = STEREO_NAMES,
    ) -> Observations:
        """Build from ``{(frame, camera): Features}``; ``camera`` is an index or one of the
        names ``cameras`` (the rig's, in order). ``n_configs`` defaults to the largest frame + 1
        (frames without any feature are allowed and stay unregistered)."""
        names = {str(c): i for i, c in enumerate(cameras)}
        cfg, cam, pt, uv = [], [], [], []
        for (c, camera), f in features.items():
            if isinstance(camera, str):
                if camera not in names:
                    raise InputError(f"camera {camera!r} is not one of {tuple(cameras)}")
                ci = names[camera]
            else:
                ci = int(camera)
                if not 0 <= ci < len(cameras):
                    raise InputError(f"camera {camera!r} is not an index 0..{len(cameras) - 1}")
            cfg.append(np.full(len(f), int(c)))
            cam.append(np.full(len(f), ci))
            pt.append(f.ids)
            uv.append(f.uv)
        if n_configs is None:
            n_configs = max((int(c) for c, _ in features), default=-1) + 1
        if not cfg:
            z = np.zeros(0, np.int64)
            return cls(z, z, z, np.zeros((0, 2)), int(n_configs), len(cameras))
        return cls(
            np.concatenate(cfg),
            np.concatenate(cam),
            np.concatenate(pt),
            np.concatenate(uv),
            int(n_configs),
            len(cameras),
        )

    @classmethod
    def from_corners(
        cls,
        detections: Mapping[tuple[int, int | str], Mapping[int, np.ndarray]],
        n_configs: int | None = None,
        cameras: Sequence[str] = STEREO_NAMES,
    ) -> Observations:
        """Build from ArUco detections ``{(frame, camera): {marker_id: corners (4, 2) px}}``
        (feature ids: :mod:`selfcal.target.aruco`); see :meth:`from_features`."""
        feats = {
            key: markers_to_features(markers, where=f"view {key}")
            for key, markers in detections.items()
        }
        return cls.from_features(feats, n_configs, cameras)

    # ------------------------------------------------------------------------ indexing
    @property
    def layout(self) -> ViewLayout:
        """The view arithmetic of these observations."""
        return ViewLayout(self.n_configs, self.n_cameras)

    @property
    def view(self) -> np.ndarray:
        """View index of each row (k,) (:class:`ViewLayout`)."""
        return self.layout.view(self.config, self.camera)

    @property
    def n_views(self) -> int:
        return self.layout.n_views

    def __len__(self) -> int:
        return len(self.config)

    def point_index(self) -> tuple[np.ndarray, np.ndarray]:
        """``(point_ids (P,), index (k,))``: the distinct point ids, sorted, and each row's index
        into them."""
        ids, inv = np.unique(self.point, return_inverse=True)
        return ids, inv

    def subset(self, mask: np.ndarray) -> Observations:
        """Rows selected by a boolean mask or index array."""
        return Observations(
            self.config[mask],
            self.camera[mask],
            self.point[mask],
            self.uv[mask],
            self.n_configs,
            self.n_cameras,
        )
