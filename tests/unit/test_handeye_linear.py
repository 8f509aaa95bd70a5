"""The hand-eye's linear start (selfcal.calibration.handeye.linear) over random motions (#28
item 3): for any well-conditioned set of flange poses, in either setup, it returns finite
transforms on the right branch: exact without noise, within a few degrees of the truth with the
board poses' noise of a real camera stage."""

from __future__ import annotations

import numpy as np
from conftest import examples
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from selfcal.calibration.handeye.calibrate import chain_motions
from selfcal.calibration.handeye.linear import linear_hand_eye
from selfcal.transforms import inv_pose, make_pose

SPREAD_RAD = 0.6
"""The flange's orientations: a random one turned by up to this much about each axis (a
robot's working range, well short of the 180-degree pairs the start leaves out)."""


def _case(seed: int, n: int, setup: str):
    """Truth X, B, the motions A (n, 4, 4) and the exact board poses C = X^-1 A B."""
    rng = np.random.default_rng(seed)
    X = make_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
    B = make_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
    R = Rotation.random(random_state=rng) * Rotation.from_rotvec(
        rng.uniform(-SPREAD_RAD, SPREAD_RAD, (n, 3)))  # fmt: skip
    A = chain_motions(setup, make_pose(R.as_matrix(), rng.uniform(-1, 1, (n, 3))))
    return X, B, A, inv_pose(X)[None] @ A @ B, rng


def _well_conditioned(A: np.ndarray) -> bool:
    """The pairs' rotation axes span more than one direction by a clear margin."""
    i, j = np.triu_indices(len(A), 1)
    w = Rotation.from_matrix((inv_pose(A[i]) @ A[j])[:, :3, :3]).as_rotvec()
    s = np.linalg.svd(w, compute_uv=False)
    return bool(s[1] > 0.25 * s[0])


def _errors(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Rotation (deg) and translation (m) errors."""
    dR = Rotation.from_matrix(T[:3, :3] @ truth[:3, :3].T).magnitude()
    return float(np.degrees(dR)), float(np.linalg.norm(T[:3, 3] - truth[:3, 3]))


@settings(max_examples=examples(60), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(4, 12),
       setup=st.sampled_from(["eye-in-hand", "eye-to-hand"]))  # fmt: skip
def test_noise_free_motions_give_the_exact_hand_eye(seed, n, setup):
    X, B, A, C, _ = _case(seed, n, setup)
    assume(_well_conditioned(A))
    X0, B0 = linear_hand_eye(A, C)
    assert np.isfinite(X0).all() and np.isfinite(B0).all()
    for T, truth in ((X0, X), (B0, B)):
        deg, m = _errors(T, truth)
        assert deg < 3e-12 and m < 1e-13  # measured worst over 3000 draws: 6e-13 deg, 2e-14 m


@settings(max_examples=examples(60), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(4, 12),
       setup=st.sampled_from(["eye-in-hand", "eye-to-hand"]))  # fmt: skip
def test_noisy_board_poses_keep_the_right_branch(seed, n, setup):
    """Board poses with 0.1 deg and 0.5 mm of noise per axis (a camera stage's, at 1 m): the start
    stays within a few degrees of the truth, never on another branch (about 180 deg off)."""
    X, B, A, C, rng = _case(seed, n, setup)
    assume(_well_conditioned(A))
    noise = make_pose(Rotation.from_rotvec(rng.normal(0.0, np.radians(0.1), (n, 3))).as_matrix(),
                      rng.normal(0.0, 0.5e-3, (n, 3)))  # fmt: skip
    X0, B0 = linear_hand_eye(A, C @ noise)
    assert np.isfinite(X0).all() and np.isfinite(B0).all()
    for T, truth in ((X0, X), (B0, B)):
        deg, m = _errors(T, truth)
        assert deg < 4.0 and m < 0.2  # measured worst over 3000 draws: 1.3 deg, 0.06 m
