"""``[camera.right]``: the right camera's own true lens and estimated intrinsics (#12, rigs of N
cameras). Its keys are [camera]'s per-camera ones; an unknown key, a bad value or a one-camera
rig is an error naming the file and the key; the dataset says each camera has its own."""

from __future__ import annotations

import dataclasses
import json

import pytest

from selfcal.acquisition.backends import plan_dataset
from selfcal.acquisition.simulator_setup import sim_setup
from selfcal.calibration.field.calibrate import dataset_camera
from selfcal.camera import CameraSet
from selfcal.config.scenario import ConfigError, load_scenario
from selfcal.io.dataset_info import read_dataset_info, write_dataset_info

LENS = "[camera]\nmodel = 'opencv'\ndistortion = { k1 = -0.25 }\nfree = ['fx', 'mu', 'k1']\n"


def write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_the_right_table_overrides_only_its_keys(tmp_path):
    s = load_scenario(write(tmp_path, LENS + "[camera.right]\nfx = 812\n"
                                     "distortion = { k1 = -0.1, p1 = 1e-3 }\n"))  # fmt: skip
    left, right = s.camera.true_models()
    assert left.fx == 800.0 and right.fx == 812.0 and isinstance(s.camera.right["fx"], float)
    assert left.coeffs[0] == -0.25 and right.coeffs[0] == -0.1 and right.coeffs[2] == 1e-3
    assert right.free == left.free and right.model_name == "opencv"
    assert s.camera.own_intrinsics and s.camera.of("left") == dataclasses.replace(
        s.camera, right={}
    )
    plain = load_scenario(write(tmp_path, LENS))
    assert not plain.camera.own_intrinsics and plain.camera.true_models()[1] == left


def test_the_simulated_rig_and_the_dataset_carry_each_camera(tmp_path):
    p = write(tmp_path, LENS + "[camera.right]\nprincipal_point_offset_px = [-9.0, 7.5]\n"
                               "free = ['fx', 'mu', 'cx', 'cy', 'k1']\n"
                               "[trajectory]\nposes = 12\n[validation]\nposes = 3\n")  # fmt: skip
    s = load_scenario(p)
    setup = sim_setup(s)
    rig = setup.rig()
    assert rig.right.cx == 319.5 - 9.0 and rig.intrinsics.cx == 319.5
    info = plan_dataset(s, setup)
    assert info.per_camera_intrinsics and info.model_of("right")[1][-1] == "k1"
    write_dataset_info(tmp_path / "dataset.json", info)
    doc = json.loads((tmp_path / "dataset.json").read_text())
    assert doc["schema_version"] == 3 and doc["per_camera_intrinsics"] is True  # 2 refuses it
    back = read_dataset_info(tmp_path / "dataset.json")
    assert back.per_camera_intrinsics and back.own_intrinsics
    cams = dataset_camera(back)
    assert isinstance(cams, CameraSet)
    assert [c.free for c in cams.cameras] == [("fx", "mu", "k1"), ("fx", "mu", "cx", "cy", "k1")]


def test_the_same_lens_for_both_estimates_one_camera_unless_the_dataset_says(tmp_path):
    s = load_scenario(write(tmp_path, LENS + "[camera.right]\ndistortion = { k1 = -0.2 }\n"))
    info = plan_dataset(s)
    assert info.camera_models is None and info.per_camera_intrinsics  # same model, own lens
    assert isinstance(dataset_camera(info), CameraSet)
    shared = dataclasses.replace(info, per_camera_intrinsics=False)
    assert not isinstance(dataset_camera(shared), CameraSet)


@pytest.mark.parametrize(
    "text, words",
    [
        ("[camera.right]\nresolution = [320, 240]\n", ["s.toml", "camera.right.resolution",
                                                       "allowed in [camera.right]"]),
        ("[camera.right]\nfx = 'big'\n", ["camera.right.fx", "number"]),
        ("[camera.right]\nfx = 1e9\n", ["s.toml", "camera.right.fx", "valid range"]),
        ("[camera.right]\ndistortion = { k1 = 0.1 }\n", ["camera.right.distortion.k1",
                                                        "'pinhole' model"]),
        ("[camera.right]\nfree = ['fx', 'k1']\n", ["camera.right.free", "'k1'"]),
        ("[camera]\ncount = 1\n[camera.right]\nfx = 810\n", ["s.toml", "camera.count = 1"]),
        (LENS + "[camera.right]\ndistortion = { k9 = 0.1 }\n", ["camera.right.distortion.k9"]),
    ],
)  # fmt: skip
def test_bad_right_tables_name_the_file_and_key(tmp_path, text, words):
    with pytest.raises(ConfigError) as err:
        load_scenario(write(tmp_path, text))
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_a_right_table_changes_the_digest_an_empty_one_does_not(tmp_path):
    from selfcal.acquisition.backends import _digested

    plain = load_scenario(write(tmp_path, LENS))
    assert "right" not in _digested(plain)["camera"]
    s = load_scenario(write(tmp_path, LENS + "[camera.right]\nfx = 812\n"))
    assert _digested(s)["camera"]["right"] == {"fx": 812.0}
