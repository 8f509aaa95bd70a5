"""The scenario key noise.msaa (issue 17): validated like every key, and at its default left out
of the dataset's scenario digest, so datasets rendered before the key existed still resume."""

from __future__ import annotations

import pytest

from selfcal.acquisition.backends import _digested
from selfcal.config.scenario import ConfigError, load_scenario, scenario_to_dict
from selfcal.io.dataset_info import scenario_digest


def test_default_and_range():
    assert load_scenario(None).noise.msaa == 4
    assert load_scenario(None, {"noise": {"msaa": 0}}).noise.msaa == 0
    with pytest.raises(ConfigError, match="noise.msaa"):
        load_scenario(None, {"noise": {"msaa": 17}})


def test_default_msaa_keeps_the_digest_of_datasets_made_before_the_key():
    s = load_scenario(None)
    before = scenario_to_dict(s)
    del before["noise"]["msaa"]  # the scenario as it was written before noise.msaa existed
    del before["target"]["board"]  # (nor target.board: left out when empty as well)
    del before["camera"]["right"]  # (nor an empty camera.right)
    del before["camera"]["skew_px"]  # (nor a zero camera.skew_px)
    del before["camera"]["setup"]  # (nor the camera on the flange, camera.setup)
    del before["camera"]["pose"]  # (nor a still camera's pose, camera.pose)
    del before["target"]["board_pose"], before["trajectory"]["joints"]  # (nor the plan's keys)
    assert scenario_digest(_digested(s)) == scenario_digest(before)
    off = load_scenario(None, {"noise": {"msaa": 0}})
    assert scenario_digest(_digested(off)) != scenario_digest(before)
    assert scenario_to_dict(s)["noise"]["msaa"] == 4  # truth.json keeps the whole scenario
