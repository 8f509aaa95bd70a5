"""Lens maps: normalised coordinates -> distorted normalised coordinates, their Jacobians and inverse.

A lens map sits between :func:`selfcal.camera.model.perspective` and the pixel map
:meth:`selfcal.camera.pinhole.Pinhole.pixels`. Both maps follow OpenCV exactly (same formulas,
same coefficient order), so values compare with ``cv2.projectPoints`` / ``cv2.fisheye`` and export
to OpenCV and ROS unchanged:

- :func:`brown_conrady` (OpenCV's default model, ROS ``plumb_bob`` / ``rational_polynomial``),
  coefficients ``(k1, k2, p1, p2, k3, k4, k5, k6)``::

      r2 = x^2 + y^2,  radial = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
      xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
      yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y

- :func:`kannala_brandt` (``cv2.fisheye``, ROS ``equidistant``), coefficients ``(k1, k2, k3,
  k4)``::

      r = |(x, y)|,  theta = atan(r),  theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8)
      (xd, yd) = theta_d / r (x, y)

Each map returns ``(xd (..., 2), J_xn (..., 2, 2), J_coeffs (..., 2, n))``. :func:`undistort`
inverts a map by Newton's method with the analytic Jacobian (used by ``unproject_normalised`` and by the
renderer's exact inverse remap).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

__all__ = ["LensMap", "brown_conrady", "brown_conrady_points", "kannala_brandt", "undistort"]

LensMap = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""``(xn (..., 2), coeffs (n,)) -> (xd (..., 2), J_xn (..., 2, 2), J_coeffs (..., 2, n))``."""


class _RadialTangential(NamedTuple):
    """The intermediate values of the rational radial-tangential map at each point (unitless)."""

    x: np.ndarray
    y: np.ndarray
    r2: np.ndarray
    a: np.ndarray  # the radial numerator 1 + k1 r^2 + k2 r^4 + k3 r^6
    b: np.ndarray  # the radial denominator 1 + k4 r^2 + k5 r^4 + k6 r^6
    radial: np.ndarray
    xd: np.ndarray  # distorted normalised coordinates (...,), (...,)
    yd: np.ndarray


def _radial_tangential(xn: np.ndarray, k: tuple[float, ...]) -> _RadialTangential:
    """The distorted normalised coordinates of ``xn`` (..., 2) and the values the Jacobians
    reuse: the one place the map's value is written out."""
    k1, k2, p1, p2, k3, k4, k5, k6 = k
    x, y = xn[..., 0], xn[..., 1]
    r2 = x * x + y * y
    r4, r6 = r2 * r2, r2 * r2 * r2
    a = 1.0 + k1 * r2 + k2 * r4 + k3 * r6
    b = 1.0 + k4 * r2 + k5 * r4 + k6 * r6
    radial = a / b
    xy = x * y
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    return _RadialTangential(x, y, r2, a, b, radial, xd, yd)


def brown_conrady(xn: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OpenCV's radial-tangential (rational) distortion of normalised coordinates ``xn`` (..., 2)
    with ``coeffs = (k1, k2, p1, p2, k3, k4, k5, k6)`` (unitless); see the module docstring."""
    xn = np.asarray(xn, dtype=float)
    k = tuple(float(c) for c in np.asarray(coeffs, float).reshape(8))
    k1, k2, p1, p2, k3, k4, k5, k6 = k
    x, y, r2, a, b, radial, xd, yd = _radial_tangential(xn, k)
    r4 = r2 * r2
    da = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4
    db = k4 + 2.0 * k5 * r2 + 3.0 * k6 * r4
    drad = (da * b - a * db) / (b * b)  # d radial / d r2
    xy = x * y
    J = np.empty(xn.shape[:-1] + (2, 2))
    J[..., 0, 0] = radial + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x
    J[..., 0, 1] = 2.0 * xy * drad + 2.0 * p1 * x + 2.0 * p2 * y
    J[..., 1, 0] = 2.0 * xy * drad + 2.0 * p1 * x + 2.0 * p2 * y
    J[..., 1, 1] = radial + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x
    Jc = np.empty(xn.shape[:-1] + (2, 8))
    powers = np.stack([r2, r4, r4 * r2], axis=-1)
    num = powers / b[..., None]  # d radial / d (k1, k2, k3)
    den = -powers * (a / (b * b))[..., None]  # ... / d (k4, k5, k6)
    for j, col in ((0, 0), (1, 1), (2, 4)):
        Jc[..., 0, col] = x * num[..., j]
        Jc[..., 1, col] = y * num[..., j]
    for j, col in ((0, 5), (1, 6), (2, 7)):
        Jc[..., 0, col] = x * den[..., j]
        Jc[..., 1, col] = y * den[..., j]
    Jc[..., 0, 2] = 2.0 * xy
    Jc[..., 1, 2] = r2 + 2.0 * y * y
    Jc[..., 0, 3] = r2 + 2.0 * x * x
    Jc[..., 1, 3] = 2.0 * xy
    return np.stack([xd, yd], axis=-1), J, Jc


def brown_conrady_points(xn: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """:func:`brown_conrady`'s distorted normalised coordinates (..., 2) alone, without its
    Jacobians: the same arithmetic, so the same numbers, at a share of the cost (a projection
    that needs no derivative, e.g. a planner's visibility test of thousands of postures)."""
    k = tuple(float(c) for c in np.asarray(coeffs, float).reshape(8))
    m = _radial_tangential(np.asarray(xn, dtype=float), k)
    return np.stack([m.xd, m.yd], axis=-1)


_SMALL_R = 1e-4
"""Below this radius the fisheye map uses its series (1 + (k1 - 1/3) r^2) for d(theta_d/r)/dr / r:
the direct formula loses eps / r^2 of relative accuracy to cancellation."""


def kannala_brandt(xn: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OpenCV's fisheye (equidistant Kannala-Brandt) map of normalised coordinates ``xn``
    (..., 2) with ``coeffs = (k1, k2, k3, k4)`` (unitless); see the module docstring."""
    xn = np.asarray(xn, dtype=float)
    k = np.asarray(coeffs, dtype=float).reshape(4)
    x, y = xn[..., 0], xn[..., 1]
    r = np.hypot(x, y)
    th = np.arctan(r)
    t2 = th * th
    powers = np.stack([t2, t2**2, t2**3, t2**4], axis=-1)  # theta^2, ^4, ^6, ^8
    poly = 1.0 + powers @ k
    dpoly = 1.0 + powers @ (k * np.array([3.0, 5.0, 7.0, 9.0]))  # d theta_d / d theta
    small = r < _SMALL_R
    r_safe = np.where(small, 1.0, r)
    th_over_r = np.where(small, 1.0, th / r_safe)
    s = th_over_r * poly  # theta_d / r
    # (d s / d r) / r = (dtheta_d/dtheta * dtheta/dr * r - theta_d) / r^3
    ds_r = (dpoly / (1.0 + r * r) * r - th * poly) / r_safe**3
    ds_r = np.where(small, 2.0 * (k[0] - 1.0 / 3.0), ds_r)
    J = np.empty(xn.shape[:-1] + (2, 2))
    J[..., 0, 0] = s + ds_r * x * x
    J[..., 0, 1] = ds_r * x * y
    J[..., 1, 0] = ds_r * x * y
    J[..., 1, 1] = s + ds_r * y * y
    g = th_over_r[..., None] * powers  # d s / d k_i = theta^(2i+1) / r
    Jc = np.stack([x[..., None] * g, y[..., None] * g], axis=-2)
    return np.stack([s * x, s * y], axis=-1), J, Jc


def undistort(
    xd: np.ndarray,
    lens: LensMap,
    coeffs: np.ndarray,
    *,
    max_iterations: int = 50,
    tol: float = 1e-15,
) -> np.ndarray:
    """Normalised coordinates ``xn`` (..., 2) with ``lens(xn, coeffs)[0] == xd``: Newton's
    method from ``xn = xd`` with the analytic 2x2 Jacobian, until every step is below ``tol``
    (or ``max_iterations``). Outside the region where the map is invertible (far beyond the
    image of an ordinary lens) the result is NaN."""
    target = np.asarray(xd, dtype=float)
    xn = target.copy()
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(max_iterations):
            f, J, _ = lens(xn, coeffs)
            e = f - target
            det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
            step = np.stack(
                [
                    (J[..., 1, 1] * e[..., 0] - J[..., 0, 1] * e[..., 1]) / det,
                    (J[..., 0, 0] * e[..., 1] - J[..., 1, 0] * e[..., 0]) / det,
                ],
                axis=-1,
            )
            xn = xn - step
            if not np.any(np.abs(step) > tol * (1.0 + np.abs(xn))):  # NaN counts as done
                break
        bad = ~np.all(np.abs(lens(xn, coeffs)[0] - target) <= 1e-9 * (1.0 + np.abs(target)), -1)
    xn[bad] = np.nan
    return xn
