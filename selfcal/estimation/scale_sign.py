"""Scale and sign of the reconstruction (paper eqs. 20-24): one known distance, one trajectory.

The reconstruction is known up to a similarity: ``k = d / d_hat`` from the distance ``d`` of two
marker centres (:func:`scale_from_markers`), and the sign of ``k`` from the nominal camera
trajectory (:func:`choose_scale_sign`, :func:`sign_from_nominal`). Lengths in m after scaling.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.errors import UsageError
from selfcal.estimation.observations import Observations
from selfcal.estimation.selfcal_errors import (
    InsufficientDataError,
    ScaleMarkerError,
    SelfCalibrationError,
)
from selfcal.target import marker_corner, marker_features
from selfcal.transforms import kabsch

__all__ = [
    "ScaleEstimate",
    "scale_from_markers",
    "rigid_align",
    "SignChoice",
    "choose_scale_sign",
    "cheirality_fraction",
    "check_scale_markers_seen",
    "sign_from_nominal",
]


@dataclass(frozen=True)
class ScaleEstimate:
    """``d_hat``: distance between the two scale-marker centres in reconstruction units;
    ``k = d / d_hat`` (positive; the sign is chosen by :func:`choose_scale_sign`)."""

    d_hat: float
    k: float
    centre_a: np.ndarray
    centre_b: np.ndarray


def scale_from_markers(
    point_ids: np.ndarray,
    X: np.ndarray,
    marker_a: int,
    marker_b: int,
    distance_m: float,
) -> ScaleEstimate:
    """Scale factor from two markers whose centres are ``distance_m`` apart (paper eqs. 21-23).

    ``point_ids`` (P,) and ``X`` (P, 3) are the reconstructed corners (NaN = not reconstructed);
    each marker centre is the mean of its corners (:mod:`selfcal.target.aruco`). Raises
    :class:`ScaleMarkerError` if a corner of either marker is missing or the distance is not
    positive.
    """
    if not (np.isfinite(distance_m) and distance_m > 0):
        raise ScaleMarkerError(f"scale distance must be a positive length in m, got {distance_m}")
    if marker_a == marker_b:
        raise ScaleMarkerError("the two scale markers must be different markers")
    ids = np.asarray(point_ids)
    X = np.asarray(X, dtype=float)
    centres = []
    for mk in (marker_a, marker_b):
        want = marker_features(int(mk))
        pos = np.searchsorted(ids, want)
        found = (pos < len(ids)) & (ids[np.minimum(pos, len(ids) - 1)] == want)
        if not found.all() or not np.isfinite(X[pos]).all():
            missing = want[~found | ~np.isfinite(X[np.minimum(pos, len(ids) - 1)]).all(axis=1)]
            corners = sorted(int(marker_corner(int(c))[1]) for c in missing)
            raise ScaleMarkerError(
                f"scale marker {mk}: corners {corners} are not in the "
                "reconstruction (never seen, seen in fewer than 2 views, or rejected as "
                "outliers); make sure both scale markers are visible in several configurations"
            )
        centres.append(X[pos].mean(axis=0))
    d_hat = float(np.linalg.norm(centres[0] - centres[1]))
    if d_hat <= 0:
        raise ScaleMarkerError("the two scale-marker centres coincide in the reconstruction")
    return ScaleEstimate(d_hat, float(distance_m) / d_hat, centres[0], centres[1])


def rigid_align(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, float]:
    """Best proper rigid transform ``T`` (4, 4) with ``T @ A ~ B`` (:func:`selfcal.transforms.kabsch`)
    for point sets (n, 3); returns ``(T, rms)`` with the RMS residual in the units of B."""
    T = kabsch(A, B)
    rms = float(np.sqrt(np.mean(np.sum((np.asarray(A) @ T[:3, :3].T + T[:3, 3] - B) ** 2, axis=1))))
    return T, rms


@dataclass(frozen=True)
class SignChoice:
    """Result of :func:`choose_scale_sign`: ``sign`` (+1/-1), the RMS distance (m) of the
    rigidly aligned trajectories for ``+|k|`` and ``-|k|``, and ``ambiguous`` when the nominal
    trajectory cannot tell them apart (coplanar/collinear camera positions)."""

    sign: int
    rms_plus_m: float
    rms_minus_m: float
    ambiguous: bool


def choose_scale_sign(
    cam_positions: np.ndarray,
    nominal_positions: np.ndarray,
    *,
    ambiguity_ratio: float = 0.8,
) -> SignChoice:
    """Choose the sign of the scale factor (paper eq. 24 and the paragraph after it).

    ``cam_positions`` (n, 3): reconstructed camera centres already multiplied by ``|k|``;
    ``nominal_positions`` (n, 3): the same cameras predicted by the nominal robot model, in the
    robot frame (unknown rigid transform to the reconstruction frame). Both candidate
    trajectories ``+C`` and ``-C`` are rigidly aligned (proper rotation + translation) to the
    nominal one and the closer one wins. ``ambiguous`` is set when the two RMS values are within
    ``ambiguity_ratio`` of each other.

    When does the sign question arise? ``-k`` maps every point ``X -> -X`` and every translation
    ``t -> -t``; the projections are unchanged (``Xc -> -Xc``), so the images alone admit both
    signs *unless* cheirality is enforced: with ``-k`` all points lie behind the cameras. The
    factorisation/essential-matrix formulation of the paper recovers ``t`` only up to sign, hence
    eq. 20's ``+-``; our reconstruction is cheirality-checked (recoverPose, PnP), so the nominal
    trajectory acts as an independent cross-check (and must agree with cheirality, which
    :func:`self_calibrate` verifies). A point reflection of the camera positions is an improper
    transform, so the two candidates differ after rigid alignment unless the positions are
    coplanar (then the reflection equals a rotation by pi and the question cannot be decided
    from the trajectory: ``ambiguous``).
    """
    C = np.asarray(cam_positions, dtype=float)
    N = np.asarray(nominal_positions, dtype=float)
    if C.shape != N.shape or C.ndim != 2 or C.shape[1] != 3:
        raise UsageError(
            f"cam_positions {C.shape} and nominal_positions {N.shape} must both be (n, 3)"
        )
    if len(C) < 3:
        raise InsufficientDataError("the sign choice needs at least 3 camera positions")
    _, rp = rigid_align(C, N)
    _, rm = rigid_align(-C, N)
    ambiguous = min(rp, rm) > ambiguity_ratio * max(rp, rm)
    return SignChoice(1 if rp <= rm else -1, rp, rm, bool(ambiguous))


def cheirality_fraction(
    T_cam_world: np.ndarray, X: np.ndarray, view: np.ndarray, pidx: np.ndarray
) -> float:
    """Fraction of observations (view, point index) whose point lies in front of the camera."""
    R = T_cam_world[view, :3, :3]
    z = np.einsum("kj,kj->k", R[:, 2], X[pidx]) + T_cam_world[view, 2, 3]
    return float(np.mean(z > 0)) if len(z) else 1.0


def check_scale_markers_seen(
    obs: Observations, active: np.ndarray, scale_markers: tuple[int, int]
) -> None:
    """Raise :class:`ScaleMarkerError` unless each scale marker is observed and seen in at least
    two views among the ``active`` (k,) observation rows (the ones the adjustment kept)."""
    view = obs.view
    marker = marker_corner(obs.point)[0]
    for mk in scale_markers:
        seen = marker == int(mk)
        n_seen = len(np.unique(view[seen]))
        n_inl = len(np.unique(view[seen & active]))
        if n_seen == 0:
            raise ScaleMarkerError(
                f"scale marker {mk} is never observed; the scale d/d_hat needs both scale "
                "markers visible in at least 2 views (better: many configurations)"
            )
        if n_inl < 2:
            raise ScaleMarkerError(
                f"scale marker {mk} is seen in {n_seen} view(s) but only {n_inl} usable "
                "view(s) remain; it must be seen in at least 2 views (better: many "
                "configurations) to be triangulated"
            )


def sign_from_nominal(
    T_world_cam: np.ndarray, nominal_cam_positions: np.ndarray, k_abs: float
) -> tuple[int, SignChoice]:
    """The sign of ``k`` from the nominal camera trajectory (:func:`choose_scale_sign`).

    ``T_world_cam`` (m, N, 4, 4) the reconstructed cameras (NaN: unregistered);
    ``nominal_cam_positions`` (m, 3) of the first camera or (m, N, 3) of every camera, robot frame
    (m). Returns ``(sign, choice)``; an ambiguous choice gives +1 (cheirality decided it). Raises
    :class:`SelfCalibrationError` when the trajectory asks for -k (mirrored nominal data) and
    ``ValueError`` for positions of the wrong shape.
    """
    m, n_cam = T_world_cam.shape[:2]
    nom = np.asarray(nominal_cam_positions, dtype=float)
    if nom.shape == (m, 3):
        C, N = T_world_cam[:, 0, :3, 3], nom
    elif nom.shape == (m, n_cam, 3):
        C, N = T_world_cam[..., :3, 3].reshape(-1, 3), nom.reshape(-1, 3)
    else:
        raise UsageError(f"nominal_cam_positions must be ({m}, 3) or ({m}, {n_cam}, 3)")
    ok = np.isfinite(C).all(axis=1) & np.isfinite(N).all(axis=1)
    choice = choose_scale_sign(k_abs * C[ok], N[ok])
    if choice.ambiguous:
        return 1, choice
    if choice.sign < 0:
        raise SelfCalibrationError(
            "the nominal camera trajectory matches the mirrored reconstruction (-k), but "
            "-k puts every point behind the cameras (cheirality). The nominal positions are "
            f"mirrored relative to the images (RMS +k {choice.rms_plus_m:.4g} m, -k "
            f"{choice.rms_minus_m:.4g} m): check the robot frame handedness, the "
            "camera mounting transform and the order of nominal_cam_positions"
        )
    return 1, choice
