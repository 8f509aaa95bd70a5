"""The source pinhole of a simulated lens (selfcal/sim/lens.py) is sized from the image's edge.

``selfcal export --format mjcf`` of the real photoneo calibration (2064 x 1544 px, a Brown-Conrady
lens) took 2.05 GB and 42 s of CPU when the sizing inverted the lens at every pixel (3.2 M Newton
solves with (H, W, 2, 8) Jacobians, four times per export: ``add_camera`` and the offscreen
buffer, for both cameras). These tests pin the cause: the rays evaluated grow with the image's
perimeter, not its area, and the edge alone gives the size every pixel's ray needs.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from selfcal.camera import BrownConrady, camera_model
from selfcal.errors import InputError
from selfcal.sim import lens as sim_lens
from selfcal.sim.lens import MARGIN_PX, LensRemap, edge_pixels, source_pinhole
from selfcal.sim.mj_camera import add_camera

# the photoneo calibration's lens (tests/data/real, `selfcal calibrate`): its x extremes lie on
# the left and right edges ~5 % from the top, not at a corner
COEFFS = {"k1": -0.146, "k2": 0.233, "p1": 2.9e-5, "p2": -8.6e-4}


def _photoneo(scale: int) -> BrownConrady:
    """The photoneo camera with an image ``scale`` times smaller (same field of view)."""
    return camera_model("opencv", fx=2258.27 / scale, mu=1.0009, cx=1009.33 / scale,
                        cy=775.44 / scale, width=2064 // scale, height=1544 // scale,
                        coeffs=COEFFS)  # fmt: skip


def test_edge_pixels_are_the_outermost_rows_and_columns_once() -> None:
    e = edge_pixels(5, 4)
    assert len(e) == 2 * (5 + 4) - 4 == len({tuple(p) for p in e})
    assert set(map(tuple, e)) == {(u, v) for u in range(5) for v in range(4)
                                  if u in (0, 4) or v in (0, 3)}  # fmt: skip
    assert len(edge_pixels(1, 3)) == 3 and len(edge_pixels(3, 1)) == 3


def test_sizing_inverts_the_lens_at_the_edge_pixels_only(monkeypatch) -> None:
    cam = _photoneo(1)
    counted: list[int] = []
    original = BrownConrady.unproject_normalised

    def spy(self, uv):
        counted.append(int(np.asarray(uv).size // 2))
        return original(self, uv)

    monkeypatch.setattr(BrownConrady, "unproject_normalised", spy)
    src = source_pinhole(cam)
    spec = mujoco.MjSpec()
    add_camera(spec.worldbody, "c", cam, np.eye(4))
    perimeter = 2 * (cam.width + cam.height) - 4
    assert counted == [perimeter, perimeter]  # not width * height = 3.2 M rays
    assert src.width > cam.width and src.height > cam.height  # the barrel's corners see more
    assert list(spec.camera("c").resolution) == [src.width, src.height]


def test_the_edge_sized_source_holds_every_pixel_s_ray_with_the_margin() -> None:
    cam = _photoneo(8)
    remap = LensRemap(cam)  # inverts every pixel; raises when one falls outside the source
    src = remap.source
    assert src == source_pinhole(cam)
    u, v = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    uv = src.pixels(cam.unproject_normalised(np.stack([u, v], axis=-1)))
    low = uv.reshape(-1, 2).min(axis=0)
    high = np.array([src.width, src.height]) - 1.0 - uv.reshape(-1, 2).max(axis=0)
    # the same box as every pixel's rays give: MARGIN_PX, rounded up to whole pixels, each side
    assert np.all(low >= MARGIN_PX) and np.all(low < MARGIN_PX + 1), low
    assert np.all(high >= MARGIN_PX) and np.all(high < MARGIN_PX + 1), high
    row = np.unravel_index(np.argmin(uv[..., 0]), u.shape)[0]
    assert 0 < row < cam.height - 1  # the extreme is mid-edge: corners alone would not do


def test_a_ray_outside_the_edge_sized_source_is_refused(monkeypatch) -> None:
    cam = _photoneo(16)
    small = source_pinhole(cam)
    small = type(small)(small.fx, small.mu, small.cx - 5.0, small.cy, small.width, small.height)
    monkeypatch.setattr(sim_lens, "source_pinhole", lambda camera, supersample=1: small)
    with pytest.raises(InputError, match=r"the ray of pixel \(0, \d+\) .* falls outside"):
        LensRemap(cam)
