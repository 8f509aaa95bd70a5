"""Marker field geometry (ground truth) and textures."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from selfcal.errors import InputError
from selfcal.sim.markers import (
    BLOCK_MARGIN_M,
    MARKER_THICKNESS_M,
    MarkerField,
    _rect_corners,
    _rects_overlap,
    make_marker_field,
    marker_texture_rgb,
)


def _square(T: np.ndarray, half: float) -> np.ndarray:
    local = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    return local @ T[:2, :2].T + T[:2, 3]


def _footprints(f: MarkerField) -> list[np.ndarray]:
    """Table footprints (polygons, m) of everything except the scale markers (on the bar)."""
    scale = {f.index_of(i) for i in f.scale_ids}
    polys = []
    for k in range(len(f.ids)):
        if k in scale:
            continue
        raised = f.support_height_m[k] > 0
        half = f.tile_size_m / 2 + (BLOCK_MARGIN_M if raised else 0.0)
        polys.append(_square(f.T_world_marker[k], half))
    L, Wd, _ = f.scale_bar_size_m
    Tb = f.scale_bar_T_world
    local = np.array([[-L / 2, -Wd / 2], [L / 2, -Wd / 2], [L / 2, Wd / 2], [-L / 2, Wd / 2]])
    polys.append(local @ Tb[:2, :2].T + Tb[:2, 3])
    return polys


def test_deterministic_per_seed():
    a, b, c = make_marker_field(seed=3), make_marker_field(seed=3), make_marker_field(seed=5)
    np.testing.assert_array_equal(a.T_world_marker, b.T_world_marker)
    np.testing.assert_array_equal(a.ids, b.ids)
    assert not np.allclose(a.T_world_marker, c.T_world_marker)


@pytest.mark.parametrize("seed", [1, 6, 7])
def test_no_overlaps_and_clear_of_base(seed):
    f = make_marker_field(seed=seed)
    polys = _footprints(f)
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            area, _ = cv2.intersectConvexConvex(
                polys[i].astype(np.float32), polys[j].astype(np.float32)
            )
            assert area <= 1e-9, f"footprints {i} and {j} overlap ({area:.2e} m^2)"
    for p in polys:  # densely sampled outline stays outside the 0.15 m base radius
        t = np.linspace(0, 1, 50)[:, None]
        edge_pts = np.concatenate([p[k] + t * (p[(k + 1) % 4] - p[k]) for k in range(4)])
        assert np.hypot(edge_pts[:, 0], edge_pts[:, 1]).min() > 0.15


def _gap(a: np.ndarray, b: np.ndarray) -> float:
    """Signed distance (m) between convex polygons ``a`` and ``b`` where they are apart (> 0:
    the least of each vertex's distance to the other polygon), <= 0 where a vertex is inside."""
    return min(-cv2.pointPolygonTest(q.astype(np.float32), (float(x), float(y)), True)
               for p, q in ((a, b), (b, a)) for x, y in p)  # fmt: skip


def test_the_overlap_test_agrees_with_opencv():
    """The placement's separating-axis test against OpenCV's intersection of the two squares,
    over random pairs that overlap by more than 1e-9 m^2 or stand more than 1e-5 m apart."""
    rng = np.random.default_rng(4)
    seen = {True: 0, False: 0}
    for _ in range(3000):
        a, b = (_rect_corners(*rng.uniform(0.0, 0.06, 2), rng.uniform(-np.pi, np.pi), 0.02, 0.02)
                for _ in range(2))  # fmt: skip
        area, _ = cv2.intersectConvexConvex(a.astype(np.float32), b.astype(np.float32))
        if area > 1e-9:
            seen[True] += 1
            assert _rects_overlap(a, b)
        elif _gap(a, b) > 1e-5:
            seen[False] += 1
            assert not _rects_overlap(a, b)
    assert min(seen.values()) > 300  # both outcomes were tested


def test_field_is_not_planar_and_has_raised_markers():
    f = make_marker_field()
    X = f.corners_world().reshape(-1, 3)
    centred = X - X.mean(axis=0)
    plane_residual = np.linalg.svd(centred, compute_uv=False)[-1] / np.sqrt(len(X))
    assert plane_residual > 0.01  # m, RMS distance from the best-fit plane
    scale = {f.index_of(i) for i in f.scale_ids}
    raised = [k for k in range(len(f.ids)) if k not in scale and f.support_height_m[k] > 0]
    assert len(raised) == round(0.35 * 20)
    h = f.support_height_m[raised]
    assert np.all((h >= 0.02) & (h <= 0.08))
    # markers lie on their supports, face up
    np.testing.assert_allclose(f.T_world_marker[:, :3, 2], np.tile([0, 0, 1.0], (len(f.ids), 1)))


def test_scale_markers_exactly_scale_length_apart():
    for length in (0.2, 0.15):
        f = make_marker_field(scale_length_m=length, seed=5)
        a, b = (f.T_world_marker[f.index_of(i), :3, 3] for i in f.scale_ids)
        assert abs(np.linalg.norm(a - b) - length) < 1e-12
        others = set(f.ids.tolist()) - set(f.scale_ids)
        assert not others & set(f.scale_ids)
        assert len(f.ids) == 22


def test_corners_order_and_size():
    f = make_marker_field()
    C = f.corners_world()
    assert C.shape == (22, 4, 3)
    side = np.linalg.norm(C[:, 1] - C[:, 0], axis=1)
    np.testing.assert_allclose(side, f.size_m, atol=1e-12)
    # TL -> TR is the marker's +x, TL -> BL its -y (cv2.aruco order, face normal +z)
    x_dir = (C[:, 1] - C[:, 0]) / f.size_m
    y_dir = (C[:, 0] - C[:, 3]) / f.size_m
    np.testing.assert_allclose(x_dir, f.T_world_marker[:, :3, 0], atol=1e-12)
    np.testing.assert_allclose(y_dir, f.T_world_marker[:, :3, 1], atol=1e-12)


def test_json_round_trip():
    f = make_marker_field(seed=9)
    g = MarkerField.from_dict(json.loads(json.dumps(f.to_dict())))
    np.testing.assert_array_equal(g.T_world_marker, f.T_world_marker)
    np.testing.assert_array_equal(g.ids, f.ids)
    assert g.scale_ids == f.scale_ids and g.scale_length_m == f.scale_length_m
    np.testing.assert_array_equal(g.corners_world(), f.corners_world())


def test_from_dict_refuses_a_scale_bar_without_three_sizes():
    d = make_marker_field(seed=9).to_dict()
    d["scale_bar_size_m"] = d["scale_bar_size_m"][:2]
    with pytest.raises(InputError, match="scale_bar_size_m .* got 2 values"):
        MarkerField.from_dict(d)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="DICT"):
        make_marker_field(dictionary="DICT_NOPE")
    with pytest.raises(ValueError, match="at most"):
        make_marker_field(n_markers=49)
    with pytest.raises(ValueError, match="could not place"):
        make_marker_field(n_markers=40, dictionary="DICT_4X4_100", extent_m=(0.2, 0.2))


def test_texture_has_quiet_zone_and_is_detectable():
    img = marker_texture_rgb("DICT_4X4_50", 11, pixels_per_module=10, quiet_zone_modules=1)
    assert img.shape == (80, 80, 3) and img.dtype == np.uint8
    assert np.all(img[:10] == 255) and np.all(img[:, :10] == 255)  # quiet zone
    assert np.all(img[10:20, 10:70] == 0)  # black border module
    canvas = np.full((200, 200, 3), 255, np.uint8)
    canvas[50:130, 60:140] = img
    corners, ids, _ = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    ).detectMarkers(canvas)
    assert ids is not None and ids.ravel().tolist() == [11]
    # black square = texture pixels 10..69 -> canvas x 70..129, y 60..119; corner TL at (69.5, 59.5)
    np.testing.assert_allclose(corners[0][0][0], [69.5, 59.5], atol=0.6)


@pytest.mark.render
def test_rendered_top_view_matches_corner_order():
    """A camera straight above the field: every detected marker's corners land on the projected
    ground-truth corners in the same order (a rotated or mirrored texture would be off by a
    marker side, >= 40 px)."""
    import mujoco

    from selfcal.camera import Intrinsics, project
    from selfcal.sim.mj_camera import T_world_cam_cv, add_camera
    from selfcal.sim.render import StereoRenderer
    from selfcal.sim.scene import scene_spec
    from selfcal.target.aruco_detect import detect_markers
    from selfcal.transforms import inv_pose

    f = make_marker_field()
    spec = scene_spec(f)
    intr = Intrinsics.centered(800.0, 1.0, 640, 480)
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.47, 0.39, 0.55]
    add_camera(spec.worldbody, "top", intr, T)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with StereoRenderer(model, 640, 480, camera_names=("top",)) as r:
        (img,) = r.render_all(data)
    det = detect_markers(img, f.dictionary)
    assert len(det) >= 15
    assert set(f.scale_ids) <= set(det)
    P = project(intr, inv_pose(T_world_cam_cv(model, data, "top")), f.corners_world())
    for mid, c in det.items():
        assert np.abs(c - P[f.index_of(mid)]).max() < 0.5, mid


@pytest.mark.parametrize("seed", [1, 4])
def test_the_scene_builds_the_fields_support_boxes(seed):
    """The rendered blocks and scale bar are the boxes of ``MarkerField.support_boxes`` (the
    field plan's lines of sight pass them): same centre, axes and half sizes, each block named
    by the marker it carries, whose tile lies on the block's top face."""
    import mujoco

    from selfcal.sim.scene import scene_spec

    f = make_marker_field(seed=seed)
    model = scene_spec(f).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    T, half, of = f.support_boxes()
    names = [f"block_{f.ids[int(np.flatnonzero(of == k)[0])]}" for k in range(len(T) - 1)]
    names.append("scalebar")
    boxes = [model.geom(i).name for i in range(model.ngeom) if model.geom(i).name.startswith(("block_", "scalebar"))]  # fmt: skip
    assert boxes == names and len(names) > 2
    for k, name in enumerate(names):
        g = model.geom(name).id
        assert np.allclose(data.geom_xpos[g], T[k][:3, 3], rtol=0.0, atol=1e-12)
        assert np.allclose(data.geom_xmat[g].reshape(3, 3), T[k][:3, :3], rtol=0.0, atol=1e-9)
        assert np.allclose(model.geom_size[g], half[k], rtol=0.0, atol=1e-12)
        for row in np.flatnonzero(of == k):  # the marker's tile lies on the box's top face
            top = T[k][:3, 3] + T[k][:3, 2] * half[k][2]
            assert abs(f.T_world_marker[row][2, 3] - MARKER_THICKNESS_M - top[2]) < 1e-12
