"""Cameras with a lens (selfcal.camera.distorted, selfcal.camera.lens, selfcal.camera.spec): projection
against OpenCV, Jacobians against central differences, unproject round trips, models by name.

Tolerances are about 3x the worst of 3000 random cameras (measured): projection vs
cv2.projectPoints / cv2.fisheye.projectPoints 0.7 / 1.5 eps of (|uv| + |c| + f); point Jacobian
vs central differences (h = 1e-5 depth) 1.8e-10 / 2.5e-10 of the largest entry; parameter
Jacobian (h = 1e-6 of the value) 5e-9 / 2.8e-9 of (largest entry + 1); unproject(project(X))
7.9 / 14.5 eps in normalised coordinates.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from test_camera import central_differences

from selfcal.camera import (
    BrownConrady,
    Fisheye,
    Pinhole,
    camera_model,
    opencv_values,
    with_pinhole,
)
from selfcal.camera.lens import kannala_brandt

EPS = np.finfo(float).eps


@st.composite
def lens_cameras(draw, kind, skewed=False):
    """A random lens camera of ``kind``; ``skewed``: with a skew ``K[0, 1]`` of up to 2 % of fx
    (cv2.projectPoints ignores it, so the comparisons with OpenCV draw none)."""
    W = draw(st.integers(64, 4000))
    H = draw(st.integers(64, 4000))
    pin = (
        draw(st.floats(100.0, 5000.0)),
        draw(st.floats(0.8, 1.25)),
        draw(st.floats(0.0, float(W))),
        draw(st.floats(0.0, float(H))),
    )
    skew = draw(st.floats(-0.02, 0.02)) * pin[0] if skewed else 0.0
    if kind == "opencv":
        c = (
            draw(st.floats(-0.4, 0.4)),
            draw(st.floats(-0.2, 0.2)),
            draw(st.floats(-0.01, 0.01)),
            draw(st.floats(-0.01, 0.01)),
            draw(st.floats(-0.05, 0.05)),
            *(draw(st.floats(0.0, 0.1)) for _ in range(3)),
        )
        return BrownConrady(*pin, W, H, BrownConrady.names, c, skew=skew)
    c = tuple(draw(st.floats(-a, a)) for a in (0.1, 0.05, 0.01, 0.005))
    return Fisheye(*pin, W, H, Fisheye.names, c, skew=skew)


RMAX = {"opencv": 0.5, "fisheye": 1.5}  # normalised radius inside which the maps are invertible


def _points(cam, seed: int, n: int = 10) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    xn = rng.uniform(-1, 1, (n, 2)) * RMAX[cam.model_name] / np.sqrt(2)
    return xn, np.c_[xn, np.ones(n)] * rng.uniform(0.01, 100, (n, 1))


def _opencv(cam, X):
    if cam.model_name == "opencv":
        ref = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs)[0]
    else:
        ref = cv2.fisheye.projectPoints(
            X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs
        )[0]
    return ref.reshape(-1, 2)


@pytest.mark.parametrize("kind,tol,tol_back", [("opencv", 2.1, 24.0), ("fisheye", 4.5, 44.0)])
@settings(max_examples=examples(100), deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1))
def test_lens_projection_matches_opencv_and_unprojects(kind, tol, tol_back, data, seed):
    cam = data.draw(lens_cameras(kind))
    xn, X = _points(cam, seed)
    uv = cam.project(X)
    scale = np.abs(uv) + np.abs([cam.cx, cam.cy]) + [cam.fx, cam.fy]
    assert np.all(np.abs(uv - _opencv(cam, X)) <= tol * EPS * scale)
    assert np.all(np.abs(cam.unproject_normalised(uv) - xn) <= tol_back * EPS)


@pytest.mark.parametrize(
    "kind,tol_pt,tol_par", [("opencv", 6e-10, 1.5e-8), ("fisheye", 8e-10, 1e-8)]
)
@settings(max_examples=examples(60), deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1))
def test_lens_jacobians_match_central_differences(kind, tol_pt, tol_par, data, seed):
    cam = data.draw(lens_cameras(kind, skewed=data.draw(st.booleans())))
    _, X = _points(cam, seed)
    uv, J_point, J_par = cam.project_jacobians(X)
    np.testing.assert_array_equal(uv, cam.project(X))
    fd_point, fd_par, _ = central_differences(cam, X, 1e-6)
    scale = np.abs(J_point).max(axis=(1, 2))[:, None, None]
    assert np.all(np.abs(fd_point - J_point) <= tol_pt * scale)
    assert np.all(np.abs(fd_par - J_par) <= tol_par * (np.abs(J_par).max() + 1))


def test_fisheye_jacobian_near_the_axis_uses_the_series():
    """Below r = 1e-4 the direct formula cancels; the series keeps the Jacobian exact."""
    k = np.array([0.08, -0.03, 0.004, -0.001])
    for r in (0.0, 1e-9, 5e-5, 2e-4):
        xn = np.array([r * 0.6, r * 0.8])
        _, J, _ = kannala_brandt(xn, k)
        h = 1e-7
        fd = np.stack(
            [(kannala_brandt(xn + h * e, k)[0] - kannala_brandt(xn - h * e, k)[0]) / (2 * h)
             for e in np.eye(2)],
            axis=-1,
        )  # fmt: skip
        np.testing.assert_allclose(J, fd, atol=1e-8)


def test_lens_restricts_jacobian_to_the_free_parameters():
    cam = BrownConrady(800.0, 1.0, 320.0, 240.0, 640, 480, ("k1", "fx", "cy"),
                       (-0.2, 0.05, 0, 0, 0, 0, 0, 0))  # fmt: skip
    assert cam.free == ("fx", "cy", "k1")  # names order
    X = np.array([[0.1, -0.2, 1.0], [0.3, 0.1, 2.0]])
    _, _, J = cam.project_jacobians(X)
    _, _, Jf = cam.project_free(X)
    np.testing.assert_array_equal(Jf, J[..., [0, 3, 5]])
    moved = cam.with_free_values(cam.free_values() + [1.0, 2.0, 0.01])
    assert (moved.fx, moved.cy, moved.coefficient("k1")) == (801.0, 242.0, pytest.approx(-0.19))
    with pytest.raises(ValueError, match="k7"):
        BrownConrady(800.0, 1.0, 320.0, 240.0, 640, 480, free=("k7",))


def test_models_by_name_and_opencv_values():
    cam = camera_model("opencv", fx=800.0, mu=1.01, cx=331.5, cy=231.5, width=640, height=480,
                       coeffs={"k1": -0.25, "p2": -5e-4}, free=["k1", "fx"])  # fmt: skip
    assert isinstance(cam, BrownConrady) and cam.free == ("fx", "k1")
    vals = opencv_values(cam)
    assert vals["fy"] == pytest.approx(808.0) and vals["k1"] == -0.25 and vals["p2"] == -5e-4
    assert list(vals)[:5] == ["fx", "fy", "cx", "cy", "skew"] and vals["skew"] == 0.0
    np.testing.assert_array_equal(cam.dist_coeffs, [-0.25, 0, 0, -5e-4, 0])
    with pytest.raises(ValueError, match="k5"):
        camera_model("fisheye", fx=1, mu=1, cx=0, cy=0, width=2, height=2, coeffs={"k5": 0.1})
    with pytest.raises(ValueError, match="p1"):
        camera_model("pinhole", fx=1, mu=1, cx=0, cy=0, width=2, height=2, free=["p1"])
    with pytest.raises(ValueError, match="stereographic"):
        camera_model("stereographic", fx=1, mu=1, cx=0, cy=0, width=2, height=2)
    start = with_pinhole(cam, Pinhole.centered(750.0, 1.0, 640, 480))
    assert isinstance(start, BrownConrady) and start.free == cam.free
    assert start.coeffs == (0.0,) * 8 and (start.cx, start.cy) == (319.5, 239.5)


def test_undistorter_maps_the_pinhole_image_back_through_the_lens():
    from selfcal.camera.undistort import Undistorter

    cam = camera_model("opencv", fx=800.0, mu=1.0, cx=331.5, cy=231.5, width=64, height=48,
                       coeffs={"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4})  # fmt: skip
    flat = Undistorter(cam)
    X = np.array([[0.01, -0.005, 1.0], [-0.02, 0.015, 0.5]])
    uv_pin = flat.pinhole.project(X)
    np.testing.assert_allclose(flat.distorted(uv_pin), cam.project(X), rtol=0, atol=1e-12)
    # an image that is a linear ramp in the camera's pixels stays the ramp at distorted()
    u, v = np.meshgrid(np.arange(64, dtype=np.float32), np.arange(48, dtype=np.float32))
    out = flat.image(u + 2 * v)
    grid = np.stack(np.meshgrid(np.arange(64.0), np.arange(48.0)), axis=-1)
    src = flat.distorted(grid)
    inside = (src[..., 0] > 0) & (src[..., 0] < 63) & (src[..., 1] > 0) & (src[..., 1] < 47)
    # bilinear interpolation is exact on a ramp: float32 rounding only (measured 1.8e-5)
    assert np.abs(out - (src[..., 0] + 2 * src[..., 1]))[inside].max() <= 6e-5
    # undistorted() inverts distorted(): the camera's pixels back into the pinhole image
    np.testing.assert_allclose(flat.undistorted(cam.project(X)), uv_pin, rtol=0, atol=1e-9)


def test_the_renderer_remaps_a_skewed_camera():
    """MuJoCo's pinhole has no skew: a camera with one is rendered as its skew-free source
    pinhole and remapped (selfcal.sim.lens). A ramp in the source pinhole's pixels, remapped, is the
    ramp at the source pixel of every output pixel's ray, and a point lands where the skewed
    camera projects it."""
    from selfcal.camera import Pinhole
    from selfcal.sim.lens import LensRemap, needs_remap

    cam = Pinhole(300.0, 1.02, 40.5, 30.5, 80, 60, skew=6.0)
    assert needs_remap(cam) and not needs_remap(Pinhole(300.0, 1.02, 40.5, 30.5, 80, 60))
    remap = LensRemap(cam)
    src = remap.source
    assert src.skew == 0.0
    u, v = np.meshgrid(
        np.arange(src.width, dtype=np.float32), np.arange(src.height, dtype=np.float32)
    )
    out = remap(u + 1000 * v)
    X = np.array([[0.03, -0.02, 1.0], [-0.05, 0.04, 2.0]])
    # a point's ray: the skewed camera's pixel leads to the source pinhole's pixel of the point
    np.testing.assert_allclose(src.pixels(cam.unproject_normalised(cam.project(X))), src.project(X),
                               rtol=0, atol=1e-9)  # fmt: skip
    # every output pixel holds the source image at its ray (bilinear is exact on a ramp:
    # float32 rounding of values up to 6.7e4, measured 0.0019)
    grid = np.stack(np.meshgrid(np.arange(80.0), np.arange(60.0)), axis=-1)
    s_uv = src.pixels(cam.unproject_normalised(grid))
    assert np.abs(out - (s_uv[..., 0] + 1000 * s_uv[..., 1])).max() < 0.006
