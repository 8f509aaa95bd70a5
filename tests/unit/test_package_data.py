"""The robot models are package data (#16 item 8): found through importlib.resources inside an
installed wheel, through the source checkout otherwise, never through the working directory.
.ci/wheel_check.sh installs the built wheel and runs the commands from an empty folder."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

import tomllib

import calib.robot_def as robot_def

ROOT = Path(__file__).resolve().parents[2]


def test_checkout_models_found_from_any_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert robot_def.models_dir() == ROOT / "models"
    assert "er4u-paper" in robot_def.list_robots()
    assert robot_def.load_robot("er4u-paper").n == 5


def test_packaged_models_preferred(tmp_path, monkeypatch):
    (tmp_path / "models" / "robots").mkdir(parents=True)
    (tmp_path / "models" / "robots" / "only-here.toml").write_text("")
    monkeypatch.setattr(importlib.resources, "files", lambda pkg: tmp_path)
    assert robot_def.models_dir() == tmp_path / "models"
    assert robot_def.list_robots() == ["only-here"]


def test_wheel_carries_models():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    wheel = cfg["tool"]["hatch"]["build"]["targets"]["wheel"]
    assert wheel["force-include"]["models"] == "calib/models"
    assert "scenarios" in wheel["packages"]  # the scenario TOML files are package data of it
