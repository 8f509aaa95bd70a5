"""A synthetic "real" dataset for ``selfcal import``: a 6-axis arm (the KR 6 R900), one camera on
its flange and a printed 11x8 chessboard, as a lab would hand them over: PNG images, a joints file
in radians and a target TOML. No simulator: the board's generated image is drawn through the true poses
into the lens camera's source pinhole image (``cv2.warpPerspective``, the homography of the board
plane), the lens (k1 = -0.2 ...) is applied by the exact inverse remap of
:class:`selfcal.sim.lens.LensRemap`, and the image is blurred slightly and given pixel noise. The true robot is the nominal one with every
MCPC parameter perturbed (1 mm, 0.3 deg standard deviation).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from selfcal.camera import BrownConrady, Pinhole, Rig
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.kinematics.trajectory import plan_postures
from selfcal.robot.definition import load_robot
from selfcal.sim.lens import LensRemap
from selfcal.target import Chessboard
from selfcal.transforms import inv_pose, make_pose

ROBOT = "kr6-r900"
BOARD = Chessboard((11, 8), 0.015)
TARGET_TOML = 'type = "chessboard"\ninner_corners = [11, 8]\nsquare_mm = 15.0\n'
W, H = 800, 600
FREE = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2")
CAMERA = BrownConrady.from_pinhole(
    Pinhole(1000.0, 1.002, W / 2 - 0.5 + 12.0, H / 2 - 0.5 - 8.0, W, H),
    (-0.2, 0.08, 5e-4, -3e-4, 0.0, 0.0, 0.0, 0.0),
    FREE,
)
"""The true camera: an ordinary lens (k1 = -0.2) and the principal point (+12, -8) px off
centre."""


@functools.cache
def _camera_remap() -> LensRemap:
    """:data:`CAMERA`'s lens remap, built on first use: 1 CPU s that every test process paid
    at collection when it was built on import, whether or not it rendered."""
    return LensRemap(CAMERA)


@dataclass(frozen=True)
class Lab:
    """The true world of the synthetic lab: robot model, camera and board pose (world, m)."""

    true_model: MCPCModel
    T_world_board: np.ndarray


def make_lab(seed: int = 0) -> Lab:
    robot = load_robot(ROBOT)
    nom = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    rng = np.random.default_rng(seed)
    scale = np.array([np.radians(0.3)] * 3 + [1e-3] * 3)
    true = MCPCModel(nom.params + rng.normal(0, 1, nom.params.shape) * scale, nom.joint_types,
                     nom.joint_offsets)  # fmt: skip
    T_home = fk_tool(true, robot.home[None])[0]
    _, pts = BOARD.layout()
    c = (pts.max(axis=0) + pts.min(axis=0)) / 2
    return Lab(true, T_home @ make_pose(np.eye(3), [-c[0], -c[1], 0.5]))


def postures(lab: Lab, n: int, seed: int) -> np.ndarray:
    """``n`` postures (rad) in which the camera sees every corner of the board."""
    robot = load_robot(ROBOT)
    _, pts = BOARD.layout()
    X = pts @ lab.T_world_board[:3, :3].T + lab.T_world_board[:3, 3]
    rig = Rig((CAMERA,), np.eye(4)[None], ("cam0",))
    span = np.radians([20.0, 12.0, 12.0, 25.0, 20.0, 60.0])
    return plan_postures(robot, lab.true_model, rig, X, n, seed=seed, min_visible=len(X), span=span)


def render(
    lab: Lab, q: np.ndarray, rng: np.random.Generator, remap: LensRemap | None = None
) -> np.ndarray:
    """The camera's gray image of the board at posture ``q`` (rad); ``remap``: the lens of
    another camera (``LensRemap(camera)``; default :data:`CAMERA`'s)."""
    remap = _camera_remap() if remap is None else remap
    T = inv_pose(fk_tool(lab.true_model, q[None])[0]) @ lab.T_world_board
    img = BOARD.image(px_per_mm=6.0)
    ppm, (x0, y0) = img.px_per_m, img.extent_m[:2]
    A = np.array([[1 / ppm, 0, x0 + 0.5 / ppm], [0, 1 / ppm, y0 + 0.5 / ppm], [0, 0, 1]])
    Hm = remap.source.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
    src = remap.source
    out = cv2.warpPerspective(img.pixels, Hm, (src.width, src.height), flags=cv2.INTER_AREA,
                              borderValue=170)  # fmt: skip
    out = remap(out)  # the lens: an exact inverse remap of the pinhole image
    out = cv2.GaussianBlur(out.astype(float), (0, 0), 0.8) + rng.normal(0, 2.0, out.shape)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def write_lab_data(lab: Lab, folder: Path, n: int, seed: int) -> tuple[Path, Path]:
    """Images ``folder/images/img_NNN.png`` and ``folder/joints.csv`` (header j1..j6, rad) of
    ``n`` postures; returns (images folder, joints file)."""
    q = postures(lab, n, seed)
    rng = np.random.default_rng(seed + 100)
    imgs = folder / "images"
    imgs.mkdir(parents=True)
    for k, qk in enumerate(q):
        cv2.imwrite(str(imgs / f"img_{k:03d}.png"), render(lab, qk, rng))
    joints = folder / "joints.csv"
    lines = [",".join(f"j{j + 1}" for j in range(q.shape[1]))]
    lines += [",".join(f"{v:.9f}" for v in row) for row in q]
    joints.write_text("\n".join(lines) + "\n")
    return imgs, joints
