"""ArUco marker field: where the markers are (ground truth) and what they look like.

World frame = robot base frame, z up; the table is the plane z = 0. Each marker is a printed
black square of side ``size_m`` (the ArUco black border included) surrounded by a white quiet zone
of ``quiet_zone_modules`` modules (outside ``size_m``). ``T_world_marker`` is the pose of the
centre of the printed face: marker z = face normal (out of the face), x to the right and y up on
the printed image. Corner order is OpenCV's ArUco order (top-left, top-right, bottom-right,
bottom-left of the upright marker image), i.e. in marker coordinates
``(-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2)``.

Some markers stand on blocks (so the field is not planar) and two "scale" markers lie on a thin
bar exactly ``scale_length_m`` apart (centre to centre): the one known distance of the method.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from selfcal.errors import InputError

__all__ = [
    "MarkerField",
    "make_marker_field",
    "marker_texture_rgb",
    "aruco_dictionary",
    "MARKER_THICKNESS_M",
    "BLOCK_MARGIN_M",
]

MARKER_THICKNESS_M = 0.001
"""Thickness of the printed marker tile (a thin box in the scene), m."""
BLOCK_MARGIN_M = 0.003
"""How much a block's / the scale bar's footprint exceeds the marker tile on each side, m."""
_BASE_CLEARANCE_M = 0.15
_GAP_M = 0.004  # minimum free gap between footprints
_MAX_COVERAGE = 0.5  # fraction of the field area that footprints may cover


def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The predefined cv2.aruco dictionary called ``name`` (e.g. ``"DICT_4X4_50"``).

    Raises ``ValueError`` naming the valid choices if ``name`` is unknown.
    """
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        valid = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise InputError(f"unknown ArUco dictionary {name!r}; choose one of {valid}")
    return cv2.aruco.getPredefinedDictionary(code)


def _modules(dictionary: str) -> int:
    """Modules across the black square (data bits + 1-module black border on each side)."""
    return int(aruco_dictionary(dictionary).markerSize) + 2


def marker_texture_rgb(
    dictionary: str, marker_id: int, pixels_per_module: int, quiet_zone_modules: int = 1
) -> np.ndarray:
    """RGB uint8 image (N, N, 3) of marker ``marker_id``, upright (row 0 = top of the marker).

    The black square spans ``(markerSize + 2) * pixels_per_module`` pixels and is surrounded by a
    white quiet zone of ``quiet_zone_modules * pixels_per_module`` pixels on each side, so
    ``N = (markerSize + 2 + 2 * quiet_zone_modules) * pixels_per_module``. Edges fall exactly on
    pixel boundaries. Raises ``ValueError`` for a bad id or non-positive sizes.
    """
    d = aruco_dictionary(dictionary)
    n_ids = d.bytesList.shape[0]
    if not 0 <= int(marker_id) < n_ids:
        raise InputError(f"marker id {marker_id} outside {dictionary} (0..{n_ids - 1})")
    if pixels_per_module < 1 or quiet_zone_modules < 0:
        raise InputError("pixels_per_module must be >= 1 and quiet_zone_modules >= 0")
    side = (d.markerSize + 2) * pixels_per_module
    img = cv2.aruco.generateImageMarker(d, int(marker_id), side, borderBits=1)
    q = quiet_zone_modules * pixels_per_module
    img = np.pad(img, q, mode="constant", constant_values=255)
    return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))


def _yaw_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [x, y, z]
    return T


@dataclass(frozen=True, eq=False)
class MarkerField:
    """Ground truth of the marker field (SI units, world = robot base frame, z up).

    ``ids`` (k,) includes the two scale markers; ``T_world_marker`` (k, 4, 4) are the printed-face
    centres; ``support_height_m`` (k,) is the height of the surface each marker lies on (0: table,
    > 0: a block or the scale bar). ``scale_bar_T_world`` (4, 4) is the centre of the bar's top
    face (x along the bar) and ``scale_bar_size_m`` its (length, width, thickness).
    """

    dictionary: str
    ids: np.ndarray
    size_m: float
    T_world_marker: np.ndarray
    scale_ids: tuple[int, int]
    scale_length_m: float
    support_height_m: np.ndarray
    scale_bar_T_world: np.ndarray
    scale_bar_size_m: tuple[float, float, float]
    quiet_zone_modules: int = 1
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=int)
        T = np.asarray(self.T_world_marker, dtype=float)
        k = ids.shape[0]
        if ids.ndim != 1 or len(set(ids.tolist())) != k:
            raise InputError("ids must be a 1-D array of distinct marker ids")
        if T.shape != (k, 4, 4):
            raise InputError(f"T_world_marker must have shape ({k}, 4, 4), got {T.shape}")
        if len(self.scale_ids) != 2 or not set(self.scale_ids) <= set(ids.tolist()):
            raise InputError(f"scale_ids {self.scale_ids} must be two ids present in ids")
        if self.size_m <= 0 or self.scale_length_m <= 0:
            raise InputError("size_m and scale_length_m must be positive (metres)")
        n_ids = aruco_dictionary(self.dictionary).bytesList.shape[0]
        if ids.min() < 0 or ids.max() >= n_ids:
            raise InputError(f"ids must lie in 0..{n_ids - 1} for {self.dictionary}")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "T_world_marker", T)
        object.__setattr__(self, "support_height_m", np.asarray(self.support_height_m, float))
        object.__setattr__(self, "scale_bar_T_world", np.asarray(self.scale_bar_T_world, float))

    @property
    def n_modules(self) -> int:
        """Modules across the black square (e.g. 6 for a 4x4 dictionary)."""
        return _modules(self.dictionary)

    @property
    def tile_size_m(self) -> float:
        """Side of the printed tile including the white quiet zone (m)."""
        return self.size_m * (self.n_modules + 2 * self.quiet_zone_modules) / self.n_modules

    def support_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The raised supports, the one source of the boxes the scene builds
        (:func:`selfcal.sim.scene.add_scene`) and the field plan sees past: ``T`` (s, 4, 4) each
        box's centre and axes in the world, ``half`` (s, 3) its half sizes (m) and
        ``of_marker`` (k,) the box each marker lies on (-1: the table); the blocks first, the
        scale bar last."""
        foot = self.tile_size_m + 2 * BLOCK_MARGIN_M
        scale_rows = {self.index_of(i) for i in self.scale_ids}
        T: list[np.ndarray] = []
        half: list[list[float]] = []
        of = -np.ones(len(self.ids), dtype=int)
        for row, h in enumerate(self.support_height_m):
            if row in scale_rows or h <= 0:
                continue
            Tb = self.T_world_marker[row].copy()
            Tb[2, 3] = h / 2
            of[row] = len(T)
            T.append(Tb)
            half.append([foot / 2, foot / 2, h / 2])
        length, width, thick = self.scale_bar_size_m
        Tb = self.scale_bar_T_world.copy()
        Tb[:3, 3] -= Tb[:3, 2] * thick / 2
        of[sorted(scale_rows)] = len(T)
        T.append(Tb)
        half.append([length / 2, width / 2, thick / 2])
        return np.array(T), np.array(half), of

    def index_of(self, marker_id: int) -> int:
        """Row of ``marker_id`` in ``ids``; raises ``KeyError`` if absent."""
        hits = np.flatnonzero(self.ids == int(marker_id))
        if hits.size == 0:
            raise InputError(f"marker id {marker_id} is not in the field")
        return int(hits[0])

    def corners_marker(self) -> np.ndarray:
        """(4, 3) corners in the marker frame, cv2.aruco order (TL, TR, BR, BL), m."""
        h = self.size_m / 2.0
        return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])

    def corners_world(self) -> np.ndarray:
        """(k, 4, 3) world corners of every marker, cv2.aruco order, m."""
        c = self.corners_marker()
        R, p = self.T_world_marker[:, :3, :3], self.T_world_marker[:, :3, 3]
        return np.einsum("kij,cj->kci", R, c) + p[:, None, :]

    def centers_world(self) -> np.ndarray:
        """(k, 3) marker centres, m."""
        return self.T_world_marker[:, :3, 3].copy()

    def to_dict(self) -> dict:
        """JSON-ready dict; lengths in metres (key names carry ``_m``)."""
        return {
            "dictionary": self.dictionary,
            "ids": self.ids.tolist(),
            "size_m": float(self.size_m),
            "T_world_marker_m": self.T_world_marker.tolist(),
            "scale_ids": [int(i) for i in self.scale_ids],
            "scale_length_m": float(self.scale_length_m),
            "support_height_m": self.support_height_m.tolist(),
            "scale_bar_T_world_m": self.scale_bar_T_world.tolist(),
            "scale_bar_size_m": [float(v) for v in self.scale_bar_size_m],
            "quiet_zone_modules": int(self.quiet_zone_modules),
            "meta": dict(self.meta),
        }

    @classmethod
    def from_dict(cls, d: dict) -> MarkerField:
        """Inverse of :meth:`to_dict`; raises ``KeyError`` naming a missing key."""
        try:
            bar = [float(v) for v in d["scale_bar_size_m"]]
            if len(bar) != 3:
                raise InputError(
                    f"marker field dict's scale_bar_size_m must be (length, width, thickness) "
                    f"in m, got {len(bar)} values"
                )
            return cls(
                dictionary=d["dictionary"],
                ids=np.asarray(d["ids"], dtype=int),
                size_m=float(d["size_m"]),
                T_world_marker=np.asarray(d["T_world_marker_m"], dtype=float),
                scale_ids=(int(d["scale_ids"][0]), int(d["scale_ids"][1])),
                scale_length_m=float(d["scale_length_m"]),
                support_height_m=np.asarray(d["support_height_m"], dtype=float),
                scale_bar_T_world=np.asarray(d["scale_bar_T_world_m"], dtype=float),
                scale_bar_size_m=(bar[0], bar[1], bar[2]),
                quiet_zone_modules=int(d.get("quiet_zone_modules", 1)),
                meta=dict(d.get("meta", {})),
            )
        except KeyError as e:
            raise InputError(f"marker field dict lacks key {e.args[0]!r}") from None


def _rect_corners(cx: float, cy: float, yaw: float, half_l: float, half_w: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    local = np.array([[half_l, half_w], [-half_l, half_w], [-half_l, -half_w], [half_l, -half_w]])
    return local @ np.array([[c, s], [-s, c]]) + [cx, cy]


def _rects_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether convex polygons ``a`` and ``b`` (4, 2) overlap (separating axis theorem), on
    Python floats: the field's placement runs this ~2000 times, where numpy's call cost on
    4-element arrays was most of the work (``selfcal run`` places the field on one core before
    its first frame). The projections may differ from numpy's matrix product in the last bit
    (no fused multiply-add); the default fields are the same (the golden tests)."""
    pa, pb = a.tolist(), b.tolist()
    for poly in (pa, pb):
        for i in range(4):
            (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % 4]
            nx, ny = y0 - y1, x1 - x0  # the edge's normal
            sa = [x * nx + y * ny for x, y in pa]
            sb = [x * nx + y * ny for x, y in pb]
            if max(sa) < min(sb) or max(sb) < min(sa):
                return False
    return True


def make_marker_field(
    n_markers: int = 20,
    seed: int = 1,
    center_xy_m: tuple[float, float] = (0.47, 0.39),
    extent_m: tuple[float, float] = (0.30, 0.30),
    size_m: float = 0.03,
    scale_length_m: float = 0.200,
    raised_fraction: float = 0.35,
    dictionary: str = "DICT_4X4_50",
    quiet_zone_modules: int = 1,
    block_height_range_m: tuple[float, float] = (0.02, 0.08),
) -> MarkerField:
    """A random, deterministic (per ``seed``) marker field on the table plane z = 0.

    ``n_markers`` field markers (ids ``0..n_markers-1``) with random yaw whose centres lie inside
    the ``extent_m`` rectangle centred at ``center_xy_m`` (tiles may overhang it by half a tile),
    with footprints (tile, or block = tile + margins) that do not overlap; ``round(raised_fraction *
    n_markers)`` of them stand on blocks of random height in ``block_height_range_m``. Plus a scale
    bar carrying the last two ids of the dictionary exactly ``scale_length_m`` apart. Everything
    stays outside a 0.15 m radius around the robot base at the origin.

    Raises ``ValueError`` if the dictionary is too small or the markers do not fit.
    """
    d = aruco_dictionary(dictionary)
    n_dict = d.bytesList.shape[0]
    if n_markers < 0 or n_markers + 2 > n_dict:
        raise InputError(f"{dictionary} has {n_dict} ids: at most {n_dict - 2} field markers")
    if not 0.0 <= raised_fraction <= 1.0:
        raise InputError("raised_fraction must lie in [0, 1]")
    nm = _modules(dictionary)
    tile = size_m * (nm + 2 * quiet_zone_modules) / nm
    cx0, cy0 = center_xy_m
    hx, hy = extent_m[0] / 2.0, extent_m[1] / 2.0
    rng = np.random.default_rng(seed)

    def inside(pts: np.ndarray) -> bool:
        pts = np.atleast_2d(pts)
        return bool(np.all(np.abs(pts[:, 0] - cx0) <= hx) and np.all(np.abs(pts[:, 1] - cy0) <= hy))

    def clear_of_base(poly: np.ndarray) -> bool:
        # a convex polygon is clear of the disc if the disc centre is outside it and every edge
        # stays farther than the radius from the origin
        for i in range(4):
            p0, p1 = poly[i], poly[(i + 1) % 4]
            e = p1 - p0
            t = min(max(-(p0 @ e) / (e @ e), 0.0), 1.0)  # np.clip's value, without its call
            if np.hypot(*(p0 + t * e)) <= _BASE_CLEARANCE_M:
                return False
        return not _rects_overlap(poly, np.zeros((4, 2)))

    # scale bar: a thin bar on the table; both scale-marker centres inside the extent
    foot_raised = tile + 2 * BLOCK_MARGIN_M
    bar_half_l = scale_length_m / 2.0 + foot_raised / 2.0
    bar_half_w = foot_raised / 2.0
    bar_thick = 0.004
    for _ in range(10000):
        bx = rng.uniform(cx0 - hx, cx0 + hx)
        by = rng.uniform(cy0 - hy, cy0 + hy)
        byaw = rng.uniform(-np.pi, np.pi)
        axis = np.array([np.cos(byaw), np.sin(byaw)])
        ends = np.array([bx, by]) + np.outer([-0.5, 0.5], scale_length_m * axis)
        bar_poly = _rect_corners(bx, by, byaw, bar_half_l + _GAP_M / 2, bar_half_w + _GAP_M / 2)
        if inside(ends) and clear_of_base(bar_poly):
            break
    else:
        raise InputError(
            f"a scale bar of {scale_length_m} m does not fit in extent {extent_m}; "
            "enlarge extent_m or shorten scale_length_m"
        )
    # field markers: which are raised, then random sequential placement without overlaps
    n_raised = int(round(raised_fraction * n_markers))
    raised = np.zeros(n_markers, dtype=bool)
    raised[rng.choice(n_markers, size=n_raised, replace=False)] = True
    heights = np.where(raised, rng.uniform(*block_height_range_m, size=n_markers), 0.0)
    halves = np.where(raised, foot_raised, tile) / 2.0 + _GAP_M / 2
    covered = float(np.sum((2 * halves) ** 2)) + 4 * bar_half_l * bar_half_w
    available = (extent_m[0] + tile) * (extent_m[1] + tile)
    if covered > _MAX_COVERAGE * available:
        raise InputError(
            f"could not place {n_markers} markers of {size_m} m in extent {extent_m}: they would "
            f"cover {covered / available:.0%} of it (random placement jams above "
            f"{_MAX_COVERAGE:.0%}); use fewer or smaller markers or a larger extent"
        )
    bar_r_out = float(np.hypot(bar_half_l, bar_half_w)) + _GAP_M / 2
    for _layout in range(50):  # random sequential placement; restart a jammed layout
        polys: list[np.ndarray] = []
        centres: list[tuple[float, float]] = []
        yaws: list[float] = []
        for j in range(n_markers):
            half = halves[j]
            for _attempt in range(2000):
                x, y = rng.uniform(cx0 - hx, cx0 + hx), rng.uniform(cy0 - hy, cy0 + hy)
                yaw = rng.uniform(-np.pi, np.pi)
                poly = _rect_corners(x, y, yaw, half, half)
                if not clear_of_base(poly):
                    continue
                r_out = half * np.sqrt(2.0)
                if np.hypot(x - bx, y - by) < r_out + bar_r_out and _rects_overlap(poly, bar_poly):
                    continue
                # the placed markers near enough to overlap (one vectorised test, the same
                # values as marker by marker), then the exact test on those alone
                if centres:
                    placed = np.asarray(centres)
                    near = np.hypot(x - placed[:, 0], y - placed[:, 1]) < (
                        r_out + halves[: len(centres)] * np.sqrt(2.0)
                    )
                    if any(_rects_overlap(poly, polys[i]) for i in np.flatnonzero(near)):
                        continue
                polys.append(poly)
                centres.append((float(x), float(y)))
                yaws.append(float(yaw))
                break
            else:
                break  # jammed: start a new layout
        if len(centres) == n_markers:
            break
    else:
        raise InputError(
            f"could not place {n_markers} markers of {size_m} m in extent {extent_m}; "
            "use fewer or smaller markers or a larger extent"
        )

    poses = [
        _yaw_pose(x, y, h + MARKER_THICKNESS_M, yaw)
        for (x, y), yaw, h in zip(centres, yaws, heights, strict=True)
    ]
    # scale markers: centres exactly scale_length_m apart along the bar axis
    z_bar = bar_thick + MARKER_THICKNESS_M
    for sgn in (-1.0, 1.0):
        q = np.array([bx, by]) + sgn * 0.5 * scale_length_m * axis
        poses.append(_yaw_pose(q[0], q[1], z_bar, byaw))
    ids = np.arange(n_markers + 2)
    ids[-2:] = [n_dict - 2, n_dict - 1]
    support = np.concatenate([heights, [bar_thick, bar_thick]])
    return MarkerField(
        dictionary=dictionary,
        ids=ids,
        size_m=float(size_m),
        T_world_marker=np.stack(poses),
        scale_ids=(int(ids[-2]), int(ids[-1])),
        scale_length_m=float(scale_length_m),
        support_height_m=support,
        scale_bar_T_world=_yaw_pose(bx, by, bar_thick, byaw),
        scale_bar_size_m=(2 * bar_half_l, 2 * bar_half_w, bar_thick),
        quiet_zone_modules=int(quiet_zone_modules),
        meta={"seed": int(seed), "n_markers": int(n_markers)},
    )
