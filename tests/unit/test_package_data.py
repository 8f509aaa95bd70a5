"""The robot models are package data (#16 item 8): found through importlib.resources inside an
installed wheel, through the source checkout otherwise, never through the working directory.
.ci/wheel_check.sh installs the built wheel and runs the commands from an empty folder."""

from __future__ import annotations

import importlib.resources
import re
from pathlib import Path

import tomllib

import selfcal.robot.definition as robot_def

ROOT = Path(__file__).resolve().parents[2]


def test_checkout_models_found_from_any_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert robot_def.models_dir() == ROOT / "models"
    assert "er4u-paper" in robot_def.list_robots()
    assert robot_def.load_robot("er4u-paper").n == 5


def test_packaged_models_preferred(tmp_path, monkeypatch):
    (tmp_path / "models" / "targets").mkdir(parents=True)
    (tmp_path / "models" / "an_arm").mkdir()
    (tmp_path / "models" / "an_arm" / "only-here.toml").write_text("")
    monkeypatch.setattr(importlib.resources, "files", lambda pkg: tmp_path)
    assert robot_def.models_dir() == tmp_path / "models"
    assert robot_def.list_robots() == ["only-here"]


def test_wheel_carries_models():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    wheel = cfg["tool"]["hatch"]["build"]["targets"]["wheel"]
    assert wheel["force-include"]["models"] == "selfcal/models"
    assert wheel["force-include"]["scenarios"] == "selfcal/scenarios"  # the shipped scenarios
    assert wheel["packages"] == ["selfcal"]  # one top-level package


def test_shipped_scenarios_found_beside_the_models(tmp_path, monkeypatch):
    from selfcal.config.scenario import default_scenario_path, scenarios_dir

    monkeypatch.chdir(tmp_path)
    assert scenarios_dir() == ROOT / "scenarios"
    assert default_scenario_path().is_file()


def test_shipped_scenarios_describe_themselves_to_a_new_user():
    """`selfcal scenarios` listed "eye-to-hand  Eye-to-hand (issue #28)" and three lines citing
    "issue #12", numbers of this project's tracker a new user cannot look up, and eye-to-hand's
    header named models/robots/ur5e.toml, which does not exist (session 25's new-user trip)."""
    from selfcal.config.shipped import SHIPPED_DIR, shipped_scenarios

    for name, description in shipped_scenarios().items():
        assert "issue #" not in description and len(description.split()) >= 5, (name, description)
    for path in SHIPPED_DIR.glob("*.toml"):
        head = "\n".join(line for line in path.read_text().splitlines() if line.startswith("#"))
        for ref in re.findall(r"\b((?:models|scenarios)/[\w./-]+\.toml)", head):
            assert (ROOT / ref).is_file(), (path.name, ref)


def test_shipped_scenarios_are_reachable_by_name_from_anywhere(tmp_path, monkeypatch, capsys):
    """`selfcal run mono-charuco` outside the checkout said "scenario file not found"."""
    from selfcal.cli.main import main
    from selfcal.config import shipped
    from selfcal.config.scenario import board_path, load_scenario, scenario_board

    monkeypatch.chdir(tmp_path)
    s = load_scenario("mono-charuco")
    assert Path(s.source) == ROOT / "scenarios" / "mono-charuco.toml"
    assert scenario_board(s) is not None
    assert main(["scenarios"]) == 0
    listed = dict(line.split(None, 1) for line in capsys.readouterr().out.splitlines())
    assert set(listed) == {p.stem for p in (ROOT / "scenarios").glob("*.toml")}
    assert listed["paper"] == "The default scenario: the paper's setting in simulation"
    # in a wheel the board's "../models/targets/..." is selfcal/models/targets/...
    wheel = tmp_path / "site"
    (wheel / "scenarios").mkdir(parents=True)
    (wheel / "scenarios" / "mono-charuco.toml").write_bytes(Path(s.source).read_bytes())
    (wheel / "calib" / "models" / "targets").mkdir(parents=True)
    board = wheel / "calib" / "models" / "targets" / "charuco.toml"
    board.write_bytes((ROOT / "models" / "targets" / "charuco.toml").read_bytes())
    monkeypatch.setattr(shipped, "SHIPPED_DIR", wheel / "scenarios")
    monkeypatch.setattr(shipped, "models_dir", lambda: wheel / "calib" / "models")
    assert board_path(load_scenario("mono-charuco")) == board


def test_one_folder_per_robot_with_its_readme_and_licence():
    """#31: a robot lived in two places (models/robots/NAME.toml and models/FOLDER/); now its
    file, generated MJCF, scene, picture, README and LICENSE share one folder."""
    from selfcal.sim.build_models import mjcf_entries

    files = robot_def.robot_files()
    assert set(files) == {"er4u-paper", "er4u-vendor", "kr6-r900", "ur5e"}
    for path in files.values():
        folder = path.parent
        assert folder.parent == ROOT / "models" and folder.name != "targets", path
        assert (folder / "README.md").is_file() and (folder / "LICENSE").is_file(), folder
    for e in mjcf_entries():  # the MJCF of each robot beside its file
        assert e.folder == files[e.name].parent and (e.folder / f"{e.name}.xml").is_file()
    assert not (ROOT / "models" / "robots").exists()
