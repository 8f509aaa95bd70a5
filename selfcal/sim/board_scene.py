"""A printed board of known geometry in the MuJoCo scene: a thin tile textured with its image.

The image is the board's own generated one (:meth:`selfcal.target.boards.Board.image`), handed to
MuJoCo in memory like the marker textures (:mod:`selfcal.sim.scene`). Frames: the board frame of
:mod:`selfcal.target.boards` (z into the board, x along the columns, y down the rows of the
printed page) is placed at ``T_world_board`` (board -> world, m); the printed face is the tile's
top (+z geom) face, whose texture shows the image upright with image x along geom +x and image
"down" along geom -y, so the geom frame is the board frame turned by 180 degrees about x.
Element names: ``<name>`` (geom), ``<name>_tex``, ``<name>_mat``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from selfcal.sim.scene import configure_visual
from selfcal.target.boards import Board
from selfcal.transforms import make_pose

__all__ = ["add_board", "board_on_table", "board_scene_spec", "BOARD_THICKNESS_M"]

BOARD_THICKNESS_M = 0.003
"""Thickness of the board tile (m); its printed face is the board's z = 0 plane."""

_FLIP_X = np.diag([1.0, -1.0, -1.0])


def _T_board_face(extent_m: tuple[float, float, float, float]) -> np.ndarray:
    """Pose (4, 4) in the board frame of the centre of the printed face (the textured geom face:
    x right, y up the page, z out of the print) of an image covering ``extent_m``."""
    x0, y0, x1, y1 = extent_m
    return make_pose(_FLIP_X, np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0]))


def board_on_table(board: Board, centre_xy_m: tuple[float, float]) -> np.ndarray:
    """``T_world_board`` (4, 4; board -> world, m) of ``board`` lying printed face up on the
    table (world z = 0 plane, its tile :data:`BOARD_THICKNESS_M` thick) with the centre of its
    printed image at ``centre_xy_m``: board x along world x, board y along world -y, board z
    (into the board) down."""
    x0, y0, x1, y1 = board.image(1.0).extent_m
    cx, cy = centre_xy_m
    return make_pose(_FLIP_X, np.array([cx - (x0 + x1) / 2, cy + (y0 + y1) / 2, BOARD_THICKNESS_M]))


def add_board(
    spec: mujoco.MjSpec,
    board: Board,
    T_world_board: np.ndarray,
    *,
    px_per_mm: float = 8.0,
    name: str = "board",
    body: mujoco.MjsBody | None = None,
) -> None:
    """Add ``board`` to ``spec`` at ``T_world_board`` (board -> world, m) as a thin matte tile
    whose face shows the board image made at ``px_per_mm`` (module docstring). No collisions.
    ``body``: the body that carries it (``T_world_board`` is then board -> that body's frame,
    e.g. a board on the flange); default the world."""
    bi = board.image(px_per_mm)
    img = np.ascontiguousarray(np.repeat(bi.pixels[:, :, None], 3, axis=2))
    tex = spec.add_texture()
    tex.name = f"{name}_tex"
    tex.type = mujoco.mjtTexture.mjTEXTURE_2D
    tex.width, tex.height, tex.nchannel = img.shape[1], img.shape[0], 3
    tex.data = img.tobytes()
    mat = spec.add_material()
    mat.name = f"{name}_mat"
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
    mat.texuniform = False
    mat.texrepeat = [1.0, 1.0]
    mat.specular = mat.shininess = mat.reflectance = 0.0
    x0, y0, x1, y1 = bi.extent_m
    T_face = np.asarray(T_world_board, dtype=float) @ _T_board_face(bi.extent_m)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T_face[:3, :3]).reshape(-1))
    g = (spec.worldbody if body is None else body).add_geom()
    g.name = name
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    g.size = [(x1 - x0) / 2, (y1 - y0) / 2, BOARD_THICKNESS_M / 2]
    g.pos = list(T_face[:3, 3] - T_face[:3, 2] * BOARD_THICKNESS_M / 2)
    g.quat = quat
    g.material = mat.name
    g.contype = g.conaffinity = 0


def board_scene_spec(
    board: Board, T_world_board: np.ndarray, size: tuple[int, int] = (640, 480), **kw
) -> mujoco.MjSpec:
    """A new ``MjSpec`` holding only ``board`` at ``T_world_board`` under an even light (no
    robot, no cameras), with the visual settings for ``size = (width, height)`` px rendering;
    ``kw``: ``px_per_mm`` (:func:`add_board`) and ``offsamples``
    (:func:`selfcal.sim.scene.configure_visual`)."""
    spec = mujoco.MjSpec()
    spec.modelname = "scorbot_selfcal_board"
    configure_visual(spec, *size, offsamples=kw.pop("offsamples", 4))
    light = spec.worldbody.add_light()
    light.name = "board_light"
    light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    light.pos = [0.0, 0.0, 2.0]
    light.dir = [0.0, 0.1, -1.0]
    light.diffuse = [0.45] * 3
    light.ambient = [0.0] * 3
    light.specular = [0.0] * 3
    add_board(spec, board, T_world_board, **kw)
    return spec
