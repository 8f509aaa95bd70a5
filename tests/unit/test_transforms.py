"""The numpy Euler angles, quaternions, rotation vectors and mean rotation of selfcal.transforms
(`selfcal fk` and `selfcal run` load no scipy.spatial) agree with scipy's Rotation, the library
they replace, including the gimbal locks and the small-angle series."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from selfcal.errors import UsageError
from selfcal.transforms import (
    matrix_from_rotvec,
    mean_rotation,
    pose_from_vec,
    quat_from_matrix,
    rotvec_from_matrix,
    rpy_from_matrix,
    vec_from_pose,
    xyz_euler_from_matrix,
)

# Measured: at most 8.9e-16 rad from scipy over 6e5 random rotations, also within 1e-5 rad of a
# gimbal lock (the same direct method); quaternions bit-identical.
ANGLE_TOL = 3e-15
EULER = {"XYZ": xyz_euler_from_matrix, "xyz": rpy_from_matrix}

unit = st.floats(-1.0, 1.0, allow_nan=False)
quats = st.tuples(unit, unit, unit, unit).filter(lambda q: np.linalg.norm(q) > 0.1)
right = [0.0, np.pi / 2, -np.pi / 2, np.pi, -np.pi, 0.3, np.pi / 4]


def _scipy_euler(R: np.ndarray, seq: str) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy warns at a gimbal lock
        return Rotation.from_matrix(R).as_euler(seq)


def _wrapped(d: np.ndarray) -> np.ndarray:
    return np.abs(np.angle(np.exp(1j * d)))  # +pi and -pi are the same angle


@settings(max_examples=examples(300), deadline=None)
@given(quats)
def test_euler_and_quaternion_match_scipy(q):
    R = Rotation.from_quat(q).as_matrix()
    for seq, f in EULER.items():
        assert _wrapped(f(R) - _scipy_euler(R, seq)).max() <= ANGLE_TOL
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    expected = np.array([w, x, y, z]) * (1.0 if w >= 0 else -1.0)
    np.testing.assert_allclose(quat_from_matrix(R), expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("seq", list(EULER))
def test_right_angles_and_gimbal_locks_match_scipy(seq):
    """Exact multiples of 90 deg (where signs of round-off pick +-180) and +-90 deg pitch."""
    angles = np.array([(a, b, g) for a in right for b in right for g in right])
    R = Rotation.from_euler(seq, angles).as_matrix()
    got = EULER[seq](R)
    assert _wrapped(got - _scipy_euler(R, seq)).max() <= ANGLE_TOL
    assert np.all(got[:, 1] >= -np.pi / 2) and np.all(got[:, 1] <= np.pi / 2)
    # the angles rebuild the rotation (at a lock the third angle is 0, the first takes it all)
    np.testing.assert_allclose(Rotation.from_euler(seq, got).as_matrix(), R, atol=3e-15)
    locked = np.abs(np.abs(angles[:, 1]) - np.pi / 2) < 1e-12
    assert np.all(got[locked, 2] == 0.0)


def test_batched_shapes():
    R = Rotation.random(6, random_state=2).as_matrix().reshape(2, 3, 3, 3)
    assert rpy_from_matrix(R).shape == (2, 3, 3)
    assert xyz_euler_from_matrix(R).shape == (2, 3, 3)
    assert quat_from_matrix(R).shape == (2, 3, 4)
    np.testing.assert_array_equal(quat_from_matrix(R)[1, 2], quat_from_matrix(R[1, 2]))


def test_one_matrix_takes_the_batched_angles():
    """xyz_euler_from_matrix of one matrix (Python floats: the gauge fixing calls it hundreds of
    times per calibration) gives the batched path's angles, at right angles and locks too."""
    angles = np.array([(a, b, g) for a in right for b in right for g in right])
    R = np.concatenate([Rotation.from_euler("XYZ", angles).as_matrix(),
                        Rotation.random(500, random_state=4).as_matrix()])  # fmt: skip
    batched = xyz_euler_from_matrix(R)
    one = np.stack([xyz_euler_from_matrix(r) for r in R])
    assert _wrapped(one - batched).max() <= ANGLE_TOL
    assert np.array_equal(one[:, 2] == 0.0, batched[:, 2] == 0.0)  # the same locks


# Measured: at most 2.0e-15 from scipy's matrices over 2e5 rotation vectors of 1e-6 to 3 rad
# (bit-identical for one vector), rotation vectors within 8.9e-16 rad over 2e5 rotations.
MATRIX_TOL = 5e-15


def _rotvecs(seed: int, n: int) -> np.ndarray:
    """Rotation vectors of random axes, their lengths from 1e-7 rad (the Taylor series below
    1e-3) to nearly pi."""
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return axes * np.exp(rng.uniform(np.log(1e-7), np.log(3.1), (n, 1)))


def test_matrices_of_rotation_vectors_match_scipy():
    w = _rotvecs(5, 4000)
    np.testing.assert_allclose(matrix_from_rotvec(w), Rotation.from_rotvec(w).as_matrix(),
                               rtol=0, atol=MATRIX_TOL)  # fmt: skip
    for v in w[:300]:  # one vector: the Python-float path
        np.testing.assert_allclose(matrix_from_rotvec(v), Rotation.from_rotvec(v).as_matrix(),
                                   rtol=0, atol=MATRIX_TOL)  # fmt: skip
    assert matrix_from_rotvec(w.reshape(2, 2000, 3)).shape == (2, 2000, 3, 3)
    assert np.array_equal(matrix_from_rotvec(np.zeros(3)), np.eye(3))


def test_rotation_vectors_of_matrices_match_scipy():
    """Also of matrices off orthonormal (both take the nearest rotation first)."""
    w = _rotvecs(6, 4000)
    R = Rotation.from_rotvec(w).as_matrix()
    np.testing.assert_allclose(rotvec_from_matrix(R), Rotation.from_rotvec(w).as_rotvec(),
                               rtol=0, atol=MATRIX_TOL)  # fmt: skip
    off = R[:200] + np.random.default_rng(7).normal(0.0, 1e-6, (200, 3, 3))
    np.testing.assert_allclose(rotvec_from_matrix(off), Rotation.from_matrix(off).as_rotvec(),
                               rtol=0, atol=MATRIX_TOL)  # fmt: skip
    with pytest.raises(UsageError, match="determinant"):
        rotvec_from_matrix(np.diag([1.0, 1.0, -1.0]))  # a mirror


def test_poses_from_vectors_round_trip():
    v = np.concatenate([_rotvecs(8, 12), np.random.default_rng(8).normal(size=(12, 3))], axis=1)
    T = pose_from_vec(v.reshape(3, 4, 6))
    assert T.shape == (3, 4, 4, 4)
    np.testing.assert_allclose(vec_from_pose(T).reshape(12, 6), v, rtol=0, atol=1e-14)


@pytest.mark.parametrize("k", [1, 2, 7, 60])
def test_the_mean_rotation_matches_scipy(k):
    R = Rotation.random(k, random_state=k).as_matrix()
    np.testing.assert_allclose(mean_rotation(R), Rotation.from_matrix(R).mean().as_matrix(),
                               rtol=0, atol=MATRIX_TOL)  # fmt: skip
    with pytest.raises(UsageError, match="at least one"):
        mean_rotation(np.zeros((0, 3, 3)))
