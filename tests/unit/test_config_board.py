"""``[target] board``: a board of known geometry chosen by its target TOML, relative to the
scenario file; every misuse is an error naming the scenario file and the key."""

from pathlib import Path

import pytest

from selfcal.config.scenario import ConfigError, load_scenario, scenario_board
from selfcal.io.target_toml import load_target, target_document

ROOT = Path(__file__).resolve().parents[2]
CHARUCO = ROOT / "models" / "targets" / "charuco.toml"


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_the_example_scenario_reads_the_board_of_its_target_file():
    s = load_scenario(ROOT / "scenarios" / "mono-charuco.toml")
    assert s.target.board == "../models/targets/charuco.toml"
    assert target_document(scenario_board(s)) == target_document(load_target(CHARUCO))
    assert s.camera.count == 1 and s.camera.model == "opencv"


def test_without_the_key_the_target_is_the_field():
    assert scenario_board(load_scenario()) is None
    assert scenario_board(load_scenario(ROOT / "scenarios" / "mono.toml")) is None


def test_the_path_is_relative_to_the_scenario_file(tmp_path):
    (tmp_path / "boards").mkdir()
    (tmp_path / "boards" / "b.toml").write_text(CHARUCO.read_text())
    sub = tmp_path / "scenarios"
    sub.mkdir()
    s = load_scenario(write(sub, '[target]\nboard = "../boards/b.toml"\n'))
    assert target_document(scenario_board(s)) == target_document(load_target(CHARUCO))


@pytest.mark.parametrize(
    "target, extra, words",
    [
        ("missing.toml", "", ["s.toml", "target.board", "no such file"]),
        ("field.toml", "", ["s.toml", "target.board", "ArUco field, not a board"]),
        ("bad.toml", "", ["s.toml", "target.board", "bad.toml", "square_mm"]),
        ("unknown.toml", "", ["s.toml", "target.board", "unknown.toml", "spacing_mm"]),
    ],
)
def test_a_bad_board_names_the_scenario_file_and_the_key(tmp_path, target, extra, words):
    (tmp_path / "field.toml").write_text('type = "field"\n')
    (tmp_path / "bad.toml").write_text('type = "chessboard"\ninner_corners = [11, 8]\n')
    (tmp_path / "unknown.toml").write_text(
        'type = "chessboard"\ninner_corners = [11, 8]\nsquare_mm = 15.0\nspacing_mm = 3.0\n'
    )
    (tmp_path / "good.toml").write_text(CHARUCO.read_text())
    with pytest.raises(ConfigError) as e:
        load_scenario(write(tmp_path, f'[target]\nboard = "{target}"\n{extra}'))
    text = str(e.value) + str(e.value.fix or "")
    for w in words:
        assert w in text, (w, text)


def test_the_field_keeps_the_digest_of_datasets_made_before_the_key():
    """An empty target.board is left out of the dataset's scenario digest (datasets acquired
    before the key existed still resume); a board changes it."""
    from selfcal.acquisition.backends import _digested
    from selfcal.config.scenario import scenario_to_dict
    from selfcal.io.dataset_info import scenario_digest

    s = load_scenario(None)
    before = scenario_to_dict(s)
    del before["noise"]["msaa"], before["target"]["board"]  # as written before the keys existed
    del before["camera"]["right"]  # an empty [camera.right] (#12) is left out as well
    del before["camera"]["skew_px"]  # and a zero skew
    del before["camera"]["setup"]  # and the camera on the flange (#28)
    del before["camera"]["pose"]  # and no still camera's pose (#30)
    del before["target"]["board_pose"], before["trajectory"]["joints"]  # and the plan's keys
    assert scenario_digest(_digested(s)) == scenario_digest(before)
    board = load_scenario(ROOT / "scenarios" / "mono-charuco.toml")
    assert "board" in _digested(board)["target"]


@pytest.mark.parametrize(
    "text, words",
    [
        ('[camera]\nsetup = "eye-on-base"\n', ["camera.setup", "eye-to-hand", "eye-on-base"]),
        ('[camera]\nsetup = "eye-to-hand"\ncount = 1\n', ["eye-to-hand", "board", "[target]"]),
        (
            '[camera]\nsetup = "eye-to-hand"\n[target]\nboard = "c.toml"\n',
            ["eye-to-hand", "camera.count = 1"],
        ),
    ],
)
def test_an_eye_to_hand_scenario_the_simulator_cannot_build_names_the_key(tmp_path, text, words):
    """[camera] setup (#28): an unknown setup, eye-to-hand without a board (it rides on the
    flange) or with the stereo pair: a ConfigError naming the file and the key."""
    (tmp_path / "c.toml").write_text(CHARUCO.read_text())
    with pytest.raises(ConfigError) as e:
        load_scenario(write(tmp_path, text))
    msg = str(e.value) + str(e.value.fix or "")
    for w in ["s.toml", *words]:
        assert w in msg, (w, msg)


def test_the_shipped_eye_to_hand_scenario_is_a_static_camera_and_a_board():
    s = load_scenario("eye-to-hand")
    assert s.camera.setup == "eye-to-hand" and s.camera.count == 1
    assert scenario_board(s) is not None
