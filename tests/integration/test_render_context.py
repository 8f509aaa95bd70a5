"""The renderer's GL context (selfcal/sim/render.py): no shadow map where no light casts a
shadow, with the same pixels."""

from __future__ import annotations

import numpy as np
import pytest

W, H = 160, 120


def _top_view(monkeypatch, *, shadows: bool, plain: bool = False):
    """The default field seen from straight above at W x H: the image, the context's shadow map
    size and the model's after the renderer started. ``plain``: the context made as MuJoCo
    makes it (before: always with the map)."""
    import mujoco

    import selfcal.sim.render as render
    from selfcal.camera import Intrinsics
    from selfcal.sim.markers import make_marker_field
    from selfcal.sim.mj_camera import add_camera
    from selfcal.sim.scene import scene_spec

    if plain:
        monkeypatch.setattr(
            render, "_context", lambda m: mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_100)
        )
    spec = scene_spec(make_marker_field(), W, H, shadows=shadows)
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.47, 0.39, 0.55]
    add_camera(spec.worldbody, "top", Intrinsics.centered(200.0, 1.0, W, H), T)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with render.StereoRenderer(model, W, H, camera_names=("top",)) as r:
        (img,) = r.render_all(data)
        return img, int(r._ctx.shadowSize), int(model.vis.quality.shadowsize)


@pytest.mark.render
def test_no_shadow_map_without_a_casting_light_and_the_same_pixels(monkeypatch):
    img, ctx_size, model_size = _top_view(monkeypatch, shadows=False)
    assert ctx_size == 0  # MuJoCo's 4096 x 4096 map (64 MB) not made
    assert model_size == 4096  # the model as it was
    ref, ref_size, _ = _top_view(monkeypatch, shadows=False, plain=True)
    assert ref_size == 4096
    assert np.array_equal(img, ref)
    assert img.std() > 10  # a picture of the field, not a blank
    _, cast_size, _ = _top_view(monkeypatch, shadows=True)
    assert cast_size == 4096  # a light that casts a shadow keeps its map
