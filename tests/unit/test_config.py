"""Scenario configuration: defaults, overrides and errors that name file, key and type."""

import pytest

from selfcal.config.scenario import ConfigError, load_scenario


def write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_default_scenario_matches_documented_keys():
    s = load_scenario()
    assert s.robot.model == "er4u-paper" and s.robot.backend == "sim"
    assert s.camera.resolution == [640, 480] and s.camera.fx == 800.0 and s.camera.mu == 1.0
    assert s.camera.baseline_mm == 60.0
    assert s.target.markers == 20 and s.target.scale_length_mm == 200.0
    assert (s.perturbation.seed, s.perturbation.translation_mm, s.perturbation.rotation_deg) == (
        1,
        1.0,
        0.5,
    )
    assert (s.trajectory.poses, s.trajectory.seed) == (30, 1)
    assert s.noise.render is True and s.noise.image_sigma == 2.0 and s.noise.pixel_sigma == 0.5
    assert s.validation.poses == 20


def test_a_file_states_only_changes(tmp_path):
    s = load_scenario(write(tmp_path, "[camera]\nfx = 900\n[noise]\nrender = false\n"))
    assert s.camera.fx == 900.0 and isinstance(s.camera.fx, float)
    assert s.noise.render is False
    assert s.camera.mu == 1.0 and s.trajectory.poses == 30


@pytest.mark.parametrize(
    "text, words",
    [
        ("[camera]\nfx = 'big'\n", ["camera.fx", "number", "str"]),
        ("[camra]\nfx = 1\n", ["unknown key 'camra'", "camera"]),
        ("[camera]\nfocal = 1\n", ["unknown key 'camera.focal'", "fx"]),
        ("[noise]\nrender = 1\n", ["noise.render", "boolean"]),
        ("[trajectory]\nposes = 2.5\n", ["trajectory.poses", "integer"]),
        ("[camera]\nresolution = [640]\n", ["camera.resolution"]),
        ("[robot]\nbackend = 'robot'\n", ["robot.backend", "hardware"]),
        ("[camera\nfx = 1\n", ["not a valid TOML"]),
        ("[robot.hardware]\ncameras = [0, 1]\n", ["robot.hardware.cameras[0]", "string"]),
    ],
)
def test_bad_files_name_the_problem(tmp_path, text, words):
    p = write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_scenario(p)
    msg = str(err.value)
    assert str(p) in msg
    for w in words:
        assert w in msg


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_scenario(tmp_path / "nope.toml")


def test_one_camera_scenario_plans_a_one_camera_dataset(tmp_path):
    """scenarios/mono.toml: ``camera.count = 1`` makes the dataset hold the left camera alone
    (the plan then only needs that camera to see the field); 3 cameras are out of range."""
    from pathlib import Path

    from selfcal.acquisition.backends import plan_dataset

    mono = Path(__file__).resolve().parents[2] / "scenarios" / "mono.toml"
    s = load_scenario(mono, overrides={"noise": {"render": False}, "trajectory": {"poses": 6}})
    assert s.camera.count == 1 and s.camera.names == ("left",)
    info = plan_dataset(s)
    assert info.cameras == ("left",) and info.camera_model == "opencv"
    assert load_scenario().camera.names == ("left", "right")
    with pytest.raises(ConfigError, match="camera.count"):
        load_scenario(write(tmp_path, "[camera]\ncount = 3\n"))
