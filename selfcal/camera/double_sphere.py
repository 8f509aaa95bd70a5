"""The double-sphere camera (Usenko, Demmel, Cremers 2018): a closed-form model past 180 deg.

A camera-frame point ``X = (x, y, z)`` (m) is projected onto two unit spheres whose centres are
``xi`` apart along the optical axis, then perspectively onto the image plane of a pinhole shifted
by ``alpha / (1 - alpha)`` of the unit (paper's eqs. 40-45)::

    d1 = |X|,  d2 = |(x, y, xi d1 + z)|,  D = alpha d2 + (1 - alpha) (xi d1 + z)
    m = (x, y) / D,  pixels = Pinhole.pixels(m)   (u = fx mx + skew my + cx, v = fy my + cy)

A point projects when ``z > -w2 d1`` (eq. 43):
``w1 = alpha / (1 - alpha)`` for ``alpha <= 1/2`` else ``(1 - alpha) / alpha``,
``w2 = (w1 + xi) / sqrt(2 w1 xi + xi^2 + 1)``: with ``w2 > 0`` the field of view passes 180 deg;
but with ``xi < 0`` and an ``alpha`` near 0 or 1 (e.g. -0.49 and 0.08, or -0.45 and 0.92) the map
folds over inside that bound: its radius stops growing with the angle off the axis, or ``D``
reaches 0. The model projects up to :attr:`DoubleSphere.half_angle`, the smaller of the two, and
unprojects no pixel to a ray beyond it.
The inverse is closed form too (eqs. 47-50): with ``m`` of the pixel and ``r^2 = |m|^2``
(reached only where ``r^2 <= 1 / (2 alpha - 1)`` when ``alpha > 1/2``)::

    mz = (1 - alpha^2 r^2) / (alpha sqrt(1 - (2 alpha - 1) r^2) + 1 - alpha)
    ray = (mz xi + sqrt(mz^2 + (1 - xi^2) r^2)) / (mz^2 + r^2) (mx, my, mz) - (0, 0, xi)

Parameters, in order: the pinhole's ``fx`` (px), ``mu = fy / fx``, ``cx``, ``cy``, ``skew`` (px,
0 in the paper: held) and ``xi``, ``alpha`` (unitless; ``alpha`` in [0, 1]). With ``xi = 0``,
``alpha = 0`` it is the pinhole; ``xi = 0``, ``alpha = 1/2`` the stereographic fisheye.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from selfcal.camera.pinhole import Pinhole, centered_principal_point

__all__ = ["DoubleSphere"]

_ANGLES = 20001
"""Angles over [0, pi] on which :attr:`DoubleSphere.half_angle` looks for a fold (0.009 deg)."""


@dataclass(frozen=True)
class DoubleSphere(Pinhole):
    """A pinhole's pixel map (``fx``, ``mu``, ``cx``, ``cy``, ``skew`` px; image ``width`` x
    ``height`` px) after the double-sphere projection with ``xi`` and ``alpha`` (module
    docstring); ``free``: the parameters an estimation adjusts."""

    names: ClassVar[tuple[str, ...]] = ("fx", "mu", "cx", "cy", "skew", "xi", "alpha")
    lens_names: ClassVar[tuple[str, ...]] = ("xi", "alpha")
    model_name: ClassVar[str] = "double_sphere"

    xi: float = 0.0
    alpha: float = 0.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "free", tuple(self.free))
        self._check_free()
        object.__setattr__(self, "free", tuple(n for n in self.names if n in self.free))

    @property
    def pinhole(self) -> Pinhole:
        """The pixel map (its ``free``: the pinhole parameters among this model's)."""
        free = tuple(n for n in self.free if n in Pinhole.names)
        return Pinhole(self.fx, self.mu, self.cx, self.cy, self.width, self.height, free,
                       skew=self.skew)  # fmt: skip

    @property
    def coeffs(self) -> tuple[float, float]:
        """``(xi, alpha)``: the values beyond the pinhole's, in ``lens_names`` order."""
        return (self.xi, self.alpha)

    def values(self) -> np.ndarray:
        return np.array([self.fx, self.mu, self.cx, self.cy, self.skew, self.xi, self.alpha])

    def with_values(self, values: np.ndarray) -> DoubleSphere:
        v = [float(x) for x in np.asarray(values, dtype=float).reshape(len(self.names))]
        return dataclasses.replace(self, fx=v[0], mu=v[1], cx=v[2], cy=v[3], skew=v[4],
                                   xi=v[5], alpha=v[6])  # fmt: skip

    # ------------------------------------------------------------ the ray model
    @property
    def w2(self) -> float:
        """The validity bound ``w2`` of eq. 43: a point projects when ``z > -w2 |X|`` (the
        half field of view is ``arccos(-w2)``)."""
        a, xi = self.alpha, self.xi
        w1 = a / (1.0 - a) if a <= 0.5 else (1.0 - a) / a
        return (w1 + xi) / np.sqrt(2.0 * w1 * xi + xi * xi + 1.0)

    @functools.cached_property
    def half_angle(self) -> float:
        """The largest angle off the optical axis (rad) the model projects one to one: eq. 43's
        ``arccos(-w2)``, or less where the radial map ``r(theta)`` stops growing or its
        denominator reaches 0 first (module docstring); the last of 20001 angles over [0, pi]
        before that."""
        th = np.linspace(0.0, np.pi, _ANGLES)
        e = self.xi + np.cos(th)
        D = self.alpha * np.sqrt(np.sin(th) ** 2 + e * e) + (1.0 - self.alpha) * e
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.sin(th) / D
        good = (D > 0.0) & (np.cos(th) > -self.w2)
        good[1:] &= np.diff(r) > 0.0
        return float(th[-1] if good.all() else th[max(int(np.argmin(good)) - 1, 0)])

    def valid(self, X_cam: np.ndarray) -> np.ndarray:
        """(...,) bool: points less than :attr:`half_angle` off the optical axis."""
        X = np.asarray(X_cam, dtype=float)
        return X[..., 2] > np.cos(self.half_angle) * np.linalg.norm(X, axis=-1)

    def depth(self, X_cam: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.asarray(X_cam, dtype=float), axis=-1)

    def sphere_map(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The projection before the pixel map: ``m`` (..., 2) of camera-frame points
        ``X_cam`` (..., 3) (m), its Jacobian w.r.t. the point (..., 2, 3) (1/m) and w.r.t.
        ``(xi, alpha)`` (..., 2, 2)."""
        X = np.asarray(X_cam, dtype=float)
        x, y, z = X[..., 0], X[..., 1], X[..., 2]
        xi, a = self.xi, self.alpha
        d1 = np.linalg.norm(X, axis=-1)
        e = xi * d1 + z
        d2 = np.sqrt(x * x + y * y + e * e)
        D = a * d2 + (1.0 - a) * e
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / D
            m = np.stack([x * inv, y * inv], axis=-1)
            de = xi * X / d1[..., None]  # d e / d X
            de[..., 2] += 1.0
            dd2 = (X * np.array([1.0, 1.0, 0.0]) + e[..., None] * de) / d2[..., None]
            dD = a * dd2 + (1.0 - a) * de  # (..., 3)
            J = -m[..., :, None] * (dD * inv[..., None])[..., None, :]
            J[..., 0, 0] += inv
            J[..., 1, 1] += inv
            dD_xi = a * e * d1 / d2 + (1.0 - a) * d1
            dD_alpha = d2 - e
            Jp = (
                -m[..., :, None]
                * (np.stack([dD_xi, dD_alpha], axis=-1) * inv[..., None])[..., None, :]
            )
        return m, J, Jp

    def project(self, X_cam: np.ndarray) -> np.ndarray:
        return self.pixels(self.sphere_map(X_cam)[0])

    def project_jacobians(self, X_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m, J_X, J_ds = self.sphere_map(X_cam)
        uv, J_m, J_pin = self.pinhole.pixels_jacobians(m)
        return uv, J_m @ J_X, np.concatenate([J_pin, J_m @ J_ds], axis=-1)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        m = self.normalised(uv)
        xi, a = self.xi, self.alpha
        r2 = np.sum(m * m, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mz = (1.0 - a * a * r2) / (a * np.sqrt(1.0 - (2.0 * a - 1.0) * r2) + 1.0 - a)
            k = (mz * xi + np.sqrt(mz * mz + (1.0 - xi * xi) * r2)) / (mz * mz + r2)
            ray = k[..., None] * np.concatenate([m, mz[..., None]], axis=-1)
            ray[..., 2] -= xi
            ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
        if a > 0.5:
            ray[r2 > 1.0 / (2.0 * a - 1.0)] = np.nan
        with np.errstate(invalid="ignore"):
            ray[ray[..., 2] < np.cos(self.half_angle) - 1e-12] = np.nan  # past a fold
        return ray

    def unproject_normalised(self, uv: np.ndarray) -> np.ndarray:
        ray = self.unproject(uv)
        with np.errstate(invalid="ignore", divide="ignore"):
            xn = ray[..., :2] / ray[..., 2:3]
        xn[~(ray[..., 2] > 0.0)] = np.nan
        return xn

    @classmethod
    def starts(cls, width: int, height: int, free: tuple[str, ...]) -> list:
        """Principal point at the centre, aspect 1, ``xi = 0``, ``alpha = 1/2`` (the
        stereographic fisheye, ``r = 2 f tan(theta / 2)``) with half fields of view across the
        shorter side of 30, 45, 60, 90, 120 and 150 deg."""
        cx, cy = centered_principal_point(width, height)
        side = 0.5 * min(width, height)
        return [
            cls(
                side / (2.0 * np.tan(np.radians(a) / 2.0)),
                1.0,
                cx,
                cy,
                int(width),
                int(height),
                tuple(free),
                xi=0.0,
                alpha=0.5,
            )  # fmt: skip
            for a in (30.0, 45.0, 60.0, 90.0, 120.0, 150.0)
        ]
