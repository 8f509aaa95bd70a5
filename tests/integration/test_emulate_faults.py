"""``selfcal emulate --fault KIND --fault-at N`` (issue #15): a person at the robot rehearses each
fault through the command line; the acquisition against that emulator stops at frame N with the
cause, keeps the frames taken before and nothing of frame N (docs/hardware.md, "Rehearsing
faults"). The same faults injected through the Python API, with resume and calibration, are in
test_hardware_e2e.py (slow)."""

from __future__ import annotations

import argparse
import threading

import pytest
import tomllib
from conftest import start_emulate_cli

from selfcal.acquisition.acquire import AcquisitionError
from selfcal.acquisition.emulate_faults import CLI_FAULTS, acquisition_fault, choose_fault
from selfcal.cli.hw import register
from selfcal.config.scenario import default_scenario_path, load_scenario
from selfcal.errors import InputError
from selfcal.io.dataset import Dataset
from selfcal.pipeline.run import run_acquire

AT = 2
ABORTED = "abort sequence (Ctrl-A, CLRBUF) sent"
CAUSE = {  # what docs/hardware.md ("Rehearsing faults") says the user sees
    "timeout": ("no prompt from the controller within 2 s", ABORTED),
    "garble": ("garbled reply", "after 3 attempts", ABORTED),
    "impact": ("IMPACT PROTECTION axis 2", ABORTED),
    "disconnect": ("serial link lost", "could not be delivered", "emergency stop"),
}


# timeout and garble wait for reply timeouts (about 3 s each on 2 busy cores): slow tier; so
# is impact (1.1 CPU s), whose cause the default tier checks through the controller in
# tests/integration/test_acl_robot.py (IMPACT PROTECTION axis 2): the command line's path to
# the stop is disconnect's, whose cause ("could not be delivered") is checked only here
@pytest.mark.parametrize(
    "kind",
    [
        pytest.param(k, marks=pytest.mark.slow) if k in ("timeout", "garble", "impact") else k
        for k in CLI_FAULTS
    ],
)
def test_emulate_fault_on_the_command_line_stops_the_acquisition(kind, tmp_path):
    scen = tmp_path / "scenario.toml"
    scen.write_text('[robot]\nmodel = "er4u-paper"\n[noise]\nrender = false\n')
    th, stop, buf, rc = start_emulate_cli(
        [str(scen), "--fault", kind, "--fault-at", str(AT), "--move-speed", "3000",
         "--frames-dir", str(tmp_path / "frames"), "--pty-link", str(tmp_path / "tty")]
    )  # fmt: skip
    try:
        text = buf.getvalue()
        assert f"fault: {kind} at acquisition frame {AT}" in text
        snippet = text[text.index("[robot.hardware]") : text.index("Ctrl-C")]
        assert tomllib.loads(snippet)["robot"]["hardware"]["port"] == str(tmp_path / "tty")
        hw = tmp_path / "hw.toml"  # the link's default reply deadline, 2 s: the timeout fault's
        # abort missed its CLRBUF prompt within 0.5 s on loaded cores (slow tier, load ~20)
        hw.write_text(
            default_scenario_path().read_text().replace('backend = "sim"', 'backend = "hardware"')
            + "\n" + snippet
            + "\n[robot.hardware.options]\nquery_timeout_s = 2.0\npoll_interval_s = 0.01\n"
        )  # fmt: skip
        s = load_scenario(hw, {"trajectory": {"poses": 6}})
        out = tmp_path / "ds"
        with pytest.raises(AcquisitionError) as ei:
            run_acquire(s, out, quiet=True)
        msg = str(ei.value)
        assert f"stopped at frame {AT} of 6" in msg, msg
        for words in CAUSE[kind]:
            assert words in msg, (words, msg)
        assert "--resume" in msg
        assert Dataset.open(out).indices.tolist() == list(range(AT))
        assert len(list((out / "frames").glob("*.png"))) == 2 * AT
    finally:
        stop.set()
        th.join(timeout=20)
    assert rc == [0] and "emulator stopped" in buf.getvalue()


def test_random_fault_is_drawn_from_the_seed_and_bad_options_are_input_errors():
    draws = {choose_fault("random", None, seed) for seed in range(40)}
    assert {k for k, _ in draws} == set(CLI_FAULTS)
    assert all(1 <= n <= 9 for _, n in draws)
    assert choose_fault("random", None, 7) == choose_fault("random", None, 7)
    assert choose_fault("impact", 4, 7) == ("impact", 4)
    with pytest.raises(InputError, match="--fault-at"):
        acquisition_fault("impact", -1)
    with pytest.raises(InputError, match="unknown --fault"):
        acquisition_fault("smoke", 1)
    parser = argparse.ArgumentParser(prog="selfcal")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["emulate", "--fault-at", "3"])
    with pytest.raises(InputError, match="--fault-at needs --fault"):
        args.func(args, threading.Event())
