"""The reprojection block's Jacobian pieces (#17): the written-out twist Jacobian and the rows'
poses gathered once give what the straightforward per-row matrix products give, and the twist
Jacobian is the derivative of the projection (central finite differences)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.camera import camera_model
from selfcal.estimation.reprojection import camera_points, projection_blocks
from selfcal.transforms import skew

LENS = {"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4}


def _problem(seed: int):
    """A lens camera, 7 views looking at 40 points about 1 m ahead, 300 random rows."""
    rng = np.random.default_rng(seed)
    cam = camera_model(
        "opencv",
        fx=801.0,
        mu=0.99,
        cx=331.0,
        cy=232.0,
        width=640,
        height=480,
        coeffs=LENS,
        free=("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"),
    )
    V, P, k = 7, 40, 300
    T = np.tile(np.eye(4), (V, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rng.normal(0.0, 0.1, (V, 3))).as_matrix()
    T[:, :3, 3] = rng.normal(0.0, 0.05, (V, 3)) + [0.0, 0.0, 1.0]
    X = rng.normal(0.0, 0.15, (P, 3))
    view, pidx = rng.integers(0, V, k), rng.integers(0, P, k)
    return cam, T, X, view, pidx


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_projection_blocks_equal_the_per_row_matrix_products(seed):
    cam, T, X, view, pidx = _problem(seed)
    uv, Jc, Jt, Jx = projection_blocks(cam, T, X, view, pidx)
    Xc = np.einsum("kij,kj->ki", T[view, :3, :3], X[pidx]) + T[view, :3, 3]
    uv0, A, Jc0 = cam.project_free(Xc)
    D = np.concatenate([np.broadcast_to(np.eye(3), (len(Xc), 3, 3)), -skew(Xc)], axis=2)
    np.testing.assert_array_equal(camera_points(T, X, view, pidx), Xc)
    np.testing.assert_array_equal(uv, uv0)
    np.testing.assert_array_equal(Jc, Jc0)
    np.testing.assert_array_equal(Jx, A @ T[view, :3, :3])
    # rounding only: entries up to ~1.3e3 px per unit; measured differences 1.1e-13 (seeds 0-3)
    np.testing.assert_allclose(Jt, A @ D, rtol=0, atol=3e-13)


def test_twist_jacobian_is_the_derivative_of_the_projection():
    cam, T, X, view, pidx = _problem(3)
    uv, _, Jt, _ = projection_blocks(cam, T, X, view, pidx)
    h = 1e-6
    for i in range(6):
        d = np.zeros(6)
        d[i] = h

        def moved(step):
            # T' = exp([v; w]) T: the camera-frame twist the block's pose pieces refer to
            E = np.eye(4)
            E[:3, :3] = Rotation.from_rotvec(step[3:]).as_matrix()
            E[:3, 3] = step[:3]
            return projection_blocks(cam, E @ T, X, view, pidx)[0]

        fd = (moved(d) - moved(-d)) / (2 * h)
        # central differences at h = 1e-6 m / rad: measured agreement 8.3e-8 px per unit
        np.testing.assert_allclose(Jt[:, :, i], fd, rtol=0, atol=2.5e-7)
    assert np.abs(Jt).max() > 100.0  # the comparison is not between zeros


@pytest.mark.parametrize("jacobian", [True, False])
def test_the_block_evaluated_by_chunks_of_rows_is_the_block_evaluated_at_once(
    monkeypatch, jacobian
):
    """ReprojectionBlock.evaluate works through its rows in chunks (bounded temporaries): with
    chunks of 7 rows (300 rows, a short last chunk) every residual and Jacobian entry is the
    one a single chunk gives, bit for bit."""
    import selfcal.estimation.reprojection as reprojection
    from selfcal.estimation.pose_models import ViewPoses

    cam, T, X, view, pidx = _problem(3)
    model = ViewPoses(T, np.ones(len(T), bool))
    uv = np.random.default_rng(1).uniform(0, 600, (len(view), 2))
    block = reprojection.ReprojectionBlock(cam, model, view, pidx, uv)
    p = np.random.default_rng(2).normal(0.0, 1e-3, model.n_params)
    values = {"intrinsics": cam.free_values(), "poses": p, "points": X.ravel()}
    whole = block.evaluate(values, jacobian)
    monkeypatch.setattr(reprojection, "CHUNK_ROWS", 7)
    chunked = block.evaluate(values, jacobian)
    np.testing.assert_array_equal(chunked.residuals, whole.residuals)
    assert len(chunked.pieces) == len(whole.pieces) == (3 if jacobian else 0)
    for a, b in zip(chunked.pieces, whole.pieces, strict=True):
        np.testing.assert_array_equal(a.J, b.J)
        assert np.isfinite(a.J).all()
