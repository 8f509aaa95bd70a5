"""The static scene around the robot: table, lights, blocks, scale bar and ArUco marker tiles.

Everything is added to a ``mujoco.MjSpec`` so that another module can attach the robot into the
same spec. Marker textures are generated in memory with cv2.aruco and handed to MuJoCo as raw
pixel data (``MjsTexture.data``); nothing is written to disk. Element names are prefixed
(``table``, ``scene_light_*``, ``block_<id>``, ``scalebar``, ``aruco_<id>``, ``aruco_tex_<id>``,
``aruco_mat_<id>``) to avoid clashes with the robot.
"""

from __future__ import annotations

import mujoco
import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.sim.markers import MARKER_THICKNESS_M, MarkerField, marker_texture_rgb

__all__ = ["add_scene", "scene_spec", "configure_visual", "PIXELS_PER_MODULE"]

PIXELS_PER_MODULE = 16
"""Texture resolution of the markers (texels per ArUco module). 16 -> 128 px for a 4x4 marker
with a 1-module quiet zone: power-of-two, so every mipmap level keeps module edges on texel
boundaries (no texture-induced corner bias)."""

_TABLE_HALF_M = 1.0
_TABLE_RGB = (0.62, 0.60, 0.56)
_BLOCK_RGBA = (0.45, 0.52, 0.62, 1.0)
_BAR_RGBA = (0.35, 0.35, 0.38, 1.0)


def _quat_from_T(T: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3]).reshape(-1))
    return q


def configure_visual(
    spec: mujoco.MjSpec, width: int = 640, height: int = 480, offsamples: int = 4
) -> None:
    """Offscreen framebuffer ``width`` x ``height`` with ``offsamples``-fold multisampling, clip
    planes suited to cameras 0.05 - 5 m from the scene, and a soft headlight.

    Sets ``stat.extent = 1 m`` explicitly (MuJoCo scales ``znear``/``zfar`` by it) so the clip
    planes do not change when the robot is attached.
    """
    if width <= 0 or height <= 0:
        raise InputError(f"image size must be positive, got {width}x{height}")
    vis = spec.visual
    vis.global_.offwidth = max(int(width), int(vis.global_.offwidth))
    vis.global_.offheight = max(int(height), int(vis.global_.offheight))
    vis.quality.offsamples = int(offsamples)
    spec.stat.extent = 1.0
    vis.map.znear = 0.005  # 5 mm
    vis.map.zfar = 10.0  # 10 m
    vis.headlight.ambient = [0.35, 0.35, 0.35]
    vis.headlight.diffuse = [0.25, 0.25, 0.25]
    vis.headlight.specular = [0.0, 0.0, 0.0]


def _matte(mat: mujoco.MjsMaterial) -> None:
    mat.specular = 0.0
    mat.shininess = 0.0
    mat.reflectance = 0.0


def add_scene(
    spec: mujoco.MjSpec, field: MarkerField | None, shadows: bool = False, markers: bool = True
) -> None:
    """Add table, lights, blocks, scale bar and marker tiles for ``field`` to ``spec``.

    Does not touch existing elements and adds no robot. Lighting is even and from above (two
    directional lights + the headlight); ``shadows`` turns on shadow casting for the key light;
    ``markers=False`` or no ``field``: table and lights only (a scene for a board,
    :mod:`selfcal.sim.board_scene`).
    Raises ``ValueError`` if ``spec`` already holds scene elements (e.g. called twice).
    """
    if any(g.name == "table" for g in spec.geoms):
        raise UsageError("spec already contains a scene (geom 'table'); call add_scene once")
    wb = spec.worldbody

    # table: a neutral, slightly mottled plane (no straight edges or squares)
    tex = spec.add_texture()
    tex.name = "table_tex"
    tex.type = mujoco.mjtTexture.mjTEXTURE_2D
    tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_FLAT
    tex.mark = mujoco.mjtMark.mjMARK_RANDOM
    tex.random = 0.05
    tex.rgb1 = list(_TABLE_RGB)
    tex.rgb2 = list(_TABLE_RGB)
    tex.markrgb = [c - 0.06 for c in _TABLE_RGB]
    tex.width = tex.height = 256
    mat = spec.add_material()
    mat.name = "table_mat"
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "table_tex"
    mat.texrepeat = [6.0, 6.0]
    _matte(mat)
    g = wb.add_geom()
    g.name = "table"
    g.type = mujoco.mjtGeom.mjGEOM_PLANE
    g.size = [_TABLE_HALF_M, _TABLE_HALF_M, 0.05]
    g.material = "table_mat"

    # lights: even illumination from above; no specular highlights
    for i, (pos, dirn, diffuse, cast) in enumerate(
        [
            ((0.4, 0.1, 2.0), (0.0, 0.15, -1.0), 0.45, shadows),
            ((0.6, 0.8, 2.0), (-0.1, -0.2, -1.0), 0.25, False),
        ]
    ):
        light = wb.add_light()
        light.name = f"scene_light_{i}"
        light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
        light.pos = list(pos)
        light.dir = list(dirn)
        light.diffuse = [diffuse] * 3
        light.ambient = [0.0] * 3
        light.specular = [0.0] * 3
        light.castshadow = bool(cast)
    if not markers or field is None:
        return

    # blocks under raised markers, the scale bar under the scale markers: the field's own boxes
    # (MarkerField.support_boxes, which the field plan's lines of sight use too)
    T_box, half, of_marker = field.support_boxes()
    for k, (T, h) in enumerate(zip(T_box, half, strict=True)):
        b = wb.add_geom()
        if k == len(T_box) - 1:
            b.name, b.rgba = "scalebar", list(_BAR_RGBA)
        else:
            b.name = f"block_{field.ids[int(np.flatnonzero(of_marker == k)[0])]}"
            b.rgba = list(_BLOCK_RGBA)
        b.type = mujoco.mjtGeom.mjGEOM_BOX
        b.size = list(h)
        b.pos = list(T[:3, 3])
        b.quat = _quat_from_T(T)

    # marker tiles: thin boxes whose top face carries the texture (upright image: texture
    # columns along marker +x, rows along marker -y; pinned by tests/integration/test_projection.py)
    tile = field.tile_size_m
    for row, mid in enumerate(field.ids):
        img = marker_texture_rgb(
            field.dictionary, int(mid), PIXELS_PER_MODULE, field.quiet_zone_modules
        )
        t = spec.add_texture()
        t.name = f"aruco_tex_{mid}"
        t.type = mujoco.mjtTexture.mjTEXTURE_2D
        t.width, t.height, t.nchannel = img.shape[1], img.shape[0], 3
        t.data = _texture_bytes(img)
        m = spec.add_material()
        m.name = f"aruco_mat_{mid}"
        m.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = t.name
        m.texuniform = False
        m.texrepeat = [1.0, 1.0]
        _matte(m)
        T = field.T_world_marker[row]
        q = wb.add_geom()
        q.name = f"aruco_{mid}"
        q.type = mujoco.mjtGeom.mjGEOM_BOX
        q.size = [tile / 2, tile / 2, MARKER_THICKNESS_M / 2]
        q.pos = list(T[:3, 3] - T[:3, 2] * MARKER_THICKNESS_M / 2)
        q.quat = _quat_from_T(T)
        q.material = m.name
        q.contype = 0
        q.conaffinity = 0


def _texture_bytes(img_rgb: np.ndarray) -> bytes:
    """Pixel data in the row order MuJoCo expects for a 2D texture on a box's +z face such that
    the image appears upright (image x along geom +x, image down along geom -y)."""
    return np.ascontiguousarray(img_rgb).tobytes()


def scene_spec(
    field: MarkerField | None,
    width: int = 640,
    height: int = 480,
    offsamples: int = 4,
    shadows: bool = False,
    markers: bool = True,
) -> mujoco.MjSpec:
    """A new ``MjSpec`` holding only the scene for ``field`` (no robot, no cameras), with the
    visual settings for ``width`` x ``height`` offscreen rendering; ``markers``: as
    :func:`add_scene`."""
    spec = mujoco.MjSpec()
    spec.modelname = "scorbot_selfcal_scene"
    configure_visual(spec, width, height, offsamples)
    add_scene(spec, field, shadows=shadows, markers=markers)
    return spec
