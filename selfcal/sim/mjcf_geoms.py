"""Adding geometry to a ``mujoco.MjSpec``: the ``visual`` and ``collision`` default classes and
the materials (``add_defaults_and_materials``), ``GeomBuilder`` (capsules, cylinders, boxes,
spheres of either class) and the pose helpers they use.

Visual geoms: no contacts, group 2, no mass. Collision geoms: group 3, ``contype=2,
conaffinity=1`` (they touch the table but not each other), mass from a nominal density.
"""

from __future__ import annotations

import mujoco
import numpy as np

from selfcal.errors import InternalError

__all__ = ["GeomBuilder", "add_defaults_and_materials", "set_pose", "unit", "box_frame"]

_ORANGE = (0.93, 0.45, 0.06, 1.0)
_GREY = (0.55, 0.56, 0.58, 1.0)
_DARK = (0.22, 0.22, 0.24, 1.0)
_BLACK = (0.05, 0.05, 0.06, 1.0)
_STEEL = (0.70, 0.72, 0.75, 1.0)

_DENSITY = 600.0  # kg/m^3 on the solid collision shapes (hollow aluminium/plastic links)


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(-1))
    return q


def set_pose(elem, T: np.ndarray) -> None:
    elem.pos = np.asarray(T[:3, 3], dtype=float).copy()
    elem.quat = _quat(T[:3, :3])


def unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _perp(v: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """Unit vector perpendicular to ``v``, as close to ``hint`` as possible."""
    v = unit(v)
    for h in (np.asarray(hint, float), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        w = h - (h @ v) * v
        if np.linalg.norm(w) > 1e-6:
            return unit(w)
    raise InternalError("unreachable")


def box_frame(x_dir: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """Rotation whose x axis is ``x_dir`` and whose z axis is as close to ``z_hint`` as possible."""
    x = unit(x_dir)
    z = _perp(x, z_hint)
    return np.column_stack([x, np.cross(z, x), z])


class GeomBuilder:
    """Adds visual / collision geoms with the right default classes."""

    def __init__(self, spec: mujoco.MjSpec) -> None:
        self.spec = spec
        self.visual = spec.find_default("visual")
        self.collision = spec.find_default("collision")

    def _geom(self, body, cls, gtype, size, material=None, **kw) -> mujoco.MjsGeom:
        g = body.add_geom(cls)
        g.type = gtype
        g.size = list(size) + [0.0] * (3 - len(size))
        if material is not None:
            g.material = material
        for key, val in kw.items():
            setattr(g, key, val)
        return g

    def capsule(self, body, p0, p1, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        ft = np.concatenate([np.asarray(p0, float), np.asarray(p1, float)])
        return self._geom(body, cls, mujoco.mjtGeom.mjGEOM_CAPSULE, [r], material, fromto=ft)

    def cylinder(self, body, p0, p1, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        ft = np.concatenate([np.asarray(p0, float), np.asarray(p1, float)])
        return self._geom(body, cls, mujoco.mjtGeom.mjGEOM_CYLINDER, [r], material, fromto=ft)

    def box(self, body, center, R, half, material=None, collision=False):
        cls = self.collision if collision else self.visual
        return self._geom(
            body,
            cls,
            mujoco.mjtGeom.mjGEOM_BOX,
            list(half),
            material,
            pos=np.asarray(center, float).copy(),
            quat=_quat(R),
        )

    def box_between(self, body, p0, p1, half_w, half_h, z_hint, material=None, collision=False):
        """A box from ``p0`` to ``p1`` (x along the segment), half sizes ``half_w`` (y), ``half_h``
        (z, as close to ``z_hint`` as possible)."""
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        d = p1 - p0
        L = float(np.linalg.norm(d))
        return self.box(
            body, (p0 + p1) / 2, box_frame(d, z_hint), [L / 2, half_w, half_h], material, collision
        )

    def sphere(self, body, center, r, material=None, collision=False):
        cls = self.collision if collision else self.visual
        return self._geom(
            body,
            cls,
            mujoco.mjtGeom.mjGEOM_SPHERE,
            [r],
            material,
            pos=np.asarray(center, float).copy(),
        )


def add_defaults_and_materials(spec: mujoco.MjSpec) -> None:
    vis = spec.add_default("visual", spec.default)
    vis.geom.contype = 0
    vis.geom.conaffinity = 0
    vis.geom.group = 2
    vis.geom.density = 0.0
    col = spec.add_default("collision", spec.default)
    col.geom.group = 3
    col.geom.contype = 2  # touches the table (contype 1) but not other robot geoms
    col.geom.conaffinity = 1
    col.geom.density = _DENSITY
    col.geom.rgba = [0.6, 0.2, 0.2, 0.5]
    for name, rgba, spec_ in (
        ("orange", _ORANGE, 0.3),
        ("grey", _GREY, 0.3),
        ("dark", _DARK, 0.2),
        ("black", _BLACK, 0.1),
        ("steel", _STEEL, 0.6),
    ):
        m = spec.add_material()
        m.name = name
        m.rgba = list(rgba)
        m.specular = spec_
        m.shininess = 0.3
        m.reflectance = 0.0
