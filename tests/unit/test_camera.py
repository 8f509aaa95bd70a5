"""The camera model (selfcal.camera): the pinhole against OpenCV and finite differences, the round
trip through unproject, the free-parameter selection, the rig and the one visibility rule.

Tolerances are about 3x what the code achieves (measured over thousands of random cameras):
projection vs cv2.projectPoints 2 eps of the terms summed (fx |x/z| + |cx|); central differences
(step h = 1e-5 of the depth, or of the parameter): 5e-10 of the point's largest entry (point);
for the parameters, in which the projection is linear, the rounding of the differenced pixels,
0.93 eps (|uv| + sum |J p|) / h (the terms summed: fx x, skew y, cx);
unproject(project(X)) 1.7 eps of the same terms divided by the focal length.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from selfcal.camera import Pinhole, Rig, Visibility, project
from selfcal.transforms import inv_pose, make_pose, pose_from_vec

EPS = np.finfo(float).eps


@st.composite
def cameras(draw, free=("fx", "mu", "cx", "cy"), skewed=False):
    """A random pinhole; ``skewed``: maybe with a skew ``K[0, 1]`` of up to 100 px either way (2x
    the smallest fx; the comparisons with cv2.projectPoints, which ignores it, draw none)."""
    W = draw(st.integers(16, 8192))
    H = draw(st.integers(16, 8192))
    return Pinhole(
        draw(st.floats(50.0, 5000.0)),
        draw(st.floats(0.5, 2.0)),
        draw(st.floats(-100.0, W + 100.0)),
        draw(st.floats(-100.0, H + 100.0)),
        W,
        H,
        free,
        skew=draw(st.one_of(st.just(0.0), st.floats(-100.0, 100.0))) if skewed else 0.0,
    )


def _points(seed: int, n: int = 30) -> np.ndarray:
    """Camera-frame points (n, 3) m: normalised coordinates in [-2, 2], depth 0.01 .. 100 m."""
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-2, 2, (n, 2)), np.ones(n)] * rng.uniform(0.01, 100, (n, 1))


@settings(max_examples=examples(200), deadline=None)
@given(cameras(), st.integers(0, 2**32 - 1))
def test_pinhole_matches_opencv_project_points(cam, seed):
    X = _points(seed)
    ref, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, None)
    xn = X[:, :2] / X[:, 2:]
    scale = np.abs(xn) * [cam.fx, cam.fy] + np.abs([cam.cx, cam.cy])
    assert np.all(np.abs(cam.project(X) - ref.reshape(-1, 2)) <= 6 * EPS * scale)


@settings(max_examples=examples(100), deadline=None)
@given(cameras(skewed=True), st.integers(0, 2**32 - 1))
def test_pinhole_jacobians_match_central_differences(cam, seed):
    X = _points(seed, 10)
    uv, J_point, J_par = cam.project_jacobians(X)
    np.testing.assert_array_equal(uv, cam.project(X))
    fd_point, fd_par, h = central_differences(cam, X, 1e-5)
    scale = np.abs(J_point).max(axis=(1, 2))[:, None, None]  # per point
    assert np.all(np.abs(fd_point - J_point) <= 1.5e-9 * scale)
    # the projection is linear in each parameter: the difference is rounding only
    terms = np.abs(J_par * cam.values()).sum(axis=-1, keepdims=True)
    rounding = EPS * (np.abs(uv)[..., None] + terms) / h
    assert np.all(np.abs(fd_par - J_par) <= 3 * rounding)


def central_differences(cam, X: np.ndarray, rel_h: float):
    """Central differences of ``cam.project`` at ``X`` (n, 3): w.r.t. the point (n, 2, 3), step
    1e-5 of the depth, and w.r.t. every parameter (n, 2, len(names)), step ``rel_h`` of
    ``max(|value|, 1)``; and those parameter steps (len(names),)."""
    J_point = np.empty(X.shape[:-1] + (2, 3))
    for i in range(3):
        h = 1e-5 * X[:, 2:3]
        e = np.eye(3)[i]
        J_point[..., i] = (cam.project(X + h * e) - cam.project(X - h * e)) / (2 * h)
    v = cam.values()
    steps = rel_h * np.maximum(np.abs(v), 1.0)
    J_par = np.empty(X.shape[:-1] + (2, len(v)))
    for i, h in enumerate(steps):
        vp, vm = v.copy(), v.copy()
        vp[i] += h
        vm[i] -= h
        J_par[..., i] = (cam.with_values(vp).project(X) - cam.with_values(vm).project(X)) / (2 * h)
    return J_point, J_par, steps


@settings(max_examples=examples(200), deadline=None)
@given(cameras(skewed=True), st.integers(0, 2**32 - 1))
def test_unproject_inverts_project(cam, seed):
    X = _points(seed)
    xn0 = X[:, :2] / X[:, 2:]
    f = np.array([cam.fx, cam.fy])
    terms = np.abs(xn0) * f + np.abs([cam.cx, cam.cy])
    terms[:, 0] += np.abs(cam.skew * xn0[:, 1]) + terms[:, 1] * abs(cam.skew) / cam.fy
    scale = terms / f  # the terms rounded, in xn units (the skew carries y's into x)
    assert np.all(np.abs(cam.unproject_normalised(cam.project(X)) - xn0) <= 5 * EPS * scale)
    # and the ray through a pixel projects back onto it, at any depth; y's rounding reaches u
    # through the skew (|skew| / fy of it: up to 4 at fx = 50, mu = 0.5, skew = 100)
    uv = np.array([[0.0, 0.0], [cam.width - 1.0, cam.height - 1.0], [cam.cx, cam.cy]])
    big = np.abs(uv).max()
    scale = big + cam.fx + abs(cam.skew) * big / cam.fy
    for z in (0.05, 3.0):
        ray = np.c_[cam.unproject_normalised(uv), np.ones(3)] * z
        assert np.abs(cam.project(ray) - uv).max() <= 4 * EPS * scale


def test_free_selection_and_parameter_names():
    cam = Pinhole.centered(800.0, 1.02, 640, 480)
    assert cam.names == ("fx", "mu", "cx", "cy", "skew") and cam.free == ("fx", "mu")
    assert (cam.cx, cam.cy) == (319.5, 239.5) and cam.fy == pytest.approx(816.0)
    np.testing.assert_array_equal(cam.free_values(), [800.0, 1.02])
    moved = cam.with_free_values([810.0, 0.99])
    assert (moved.fx, moved.mu, moved.cx, moved.cy) == (810.0, 0.99, 319.5, 239.5)
    X = _points(3)
    _, _, J_all = cam.project_jacobians(X)
    _, _, J_free = cam.project_free(X)
    np.testing.assert_array_equal(J_free, J_all[..., :2])
    pp = Pinhole(800.0, 1.0, 300.0, 200.0, 640, 480, free=("cx", "cy", "fx"))
    np.testing.assert_array_equal(pp.free_values(), [300.0, 200.0, 800.0])
    _, _, J_pp = pp.project_free(X)
    np.testing.assert_array_equal(J_pp, pp.project_jacobians(X)[2][..., [2, 3, 0]])
    with pytest.raises(ValueError, match="free camera parameters"):
        Pinhole(800.0, 1.0, 300.0, 200.0, 640, 480, free=("fx", "k1"))
    with pytest.raises(ValueError, match="free camera parameters"):
        Pinhole(800.0, 1.0, 300.0, 200.0, 640, 480, free=("fx", "fx"))


def test_project_through_a_pose_and_the_rig():
    cam = Pinhole.centered(700.0, 1.0, 640, 480)
    T_world_left = make_pose(pose_from_vec(np.r_[0.1, -0.2, 0.3, 0, 0, 0])[:3, :3], [0.1, 0, -1])
    T_left_right = pose_from_vec(np.r_[0.0, 0.05, 0.0, 0.06, 0.0, 0.0])
    rig = Rig.stereo(cam, T_left_right)
    X = np.array([[0.05, 0.02, 0.1], [-0.1, 0.03, 0.2]])
    T_world_cams = rig.T_world_cams(T_world_left[None])[0]
    np.testing.assert_allclose(T_world_cams[1], T_world_left @ T_left_right, atol=1e-15)
    np.testing.assert_allclose(
        rig.T_cams_world(inv_pose(T_world_left)[None])[0], inv_pose(T_world_cams), atol=1e-14
    )
    Xc = X @ inv_pose(T_world_cams[1])[:3, :3].T + inv_pose(T_world_cams[1])[:3, 3]
    np.testing.assert_allclose(project(cam, inv_pose(T_world_cams[1]), X), cam.project(Xc))
    assert rig.n_cameras == 2 and rig.names == ("left", "right")
    with pytest.raises(ValueError, match="identity"):
        Rig((cam, cam), np.stack([T_left_right, np.eye(4)]), ("a", "b"))
    with pytest.raises(ValueError, match="N names"):
        Rig((cam,), np.eye(4)[None], ("a", "b"))


def test_the_visibility_rule():
    cam = Pinhole.centered(500.0, 1.0, 640, 480)
    rule = Visibility(margin_px=10.0, min_depth_m=0.1, max_depth_m=2.0, max_incidence_deg=60.0)
    T = np.eye(4)[None]  # camera at the origin looking along +z
    u_edge = (640 - 1 - 10.0 - cam.cx) / cam.fx  # normalised x of the margin's edge
    X = np.array(
        [
            [0.0, 0.0, 1.0],  # centre: seen
            [0.0, 0.0, -1.0],  # behind
            [0.0, 0.0, 0.05],  # too close
            [0.0, 0.0, 3.0],  # too far
            [(u_edge - 1e-6), 0.0, 1.0],  # just inside the margin
            [(u_edge + 1e-6), 0.0, 1.0],  # just outside it
        ]
    )
    np.testing.assert_array_equal(rule.points(cam, T, X)[0], [1, 0, 0, 0, 1, 0])

    # facing: a surface at the centre tilted by 50 deg is seen, by 70 deg not, turned away not
    def tilted(deg):
        return np.array([np.sin(np.radians(deg)), 0.0, -np.cos(np.radians(deg))])

    n = np.stack([tilted(0), tilted(50), tilted(70), tilted(180)])
    P = np.tile([0.0, 0.0, 1.0], (4, 1))
    np.testing.assert_array_equal(rule.points(cam, T, P, n)[0], [1, 1, 0, 0])
    # a marker is seen when all corners are in view and its centre faces the camera
    h = 0.02
    corners = np.array([[-h, -h, 1.0], [h, -h, 1.0], [h, h, 1.0], [-h, h, 1.0]])
    off = corners + [u_edge - h / 2, 0.0, 0.0]  # one side beyond the margin
    seen = rule.markers(cam, T, np.stack([corners, off, corners]), n[[0, 0, 3]])[0]
    np.testing.assert_array_equal(seen, [1, 0, 0])
    # the rig asks every camera: the right one 3 m to the side sees nothing
    rig = Rig.stereo(cam, make_pose(np.eye(3), [3.0, 0.0, 0.0]))
    both = rig.visible_points(rule, T, X)
    assert both.shape == (1, 2, len(X))
    np.testing.assert_array_equal(both[0, 0], rule.points(cam, T, X)[0])
    assert not both[0, 1].any()
