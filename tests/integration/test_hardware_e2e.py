"""The hardware path end to end: ``[robot] backend = "hardware"`` against the ACL emulator whose arm
is the scenario's simulated robot (``selfcal.acquisition.emulator_backend.SimEmulatorBackend``).

The scenario is ``scenarios/paper.toml`` with the one flag switched and the ``[robot.hardware]``
table the emulator prints; acquisition runs through ``AclRobot`` (serial dialogue on a pty,
encoder counts, image files read by ``selfcal.hw.cameras``), calibration never sees truth, and the test,
which holds the simulated robot, compares the calibrated model with the truth and with the sim
backend on the same scenario. Faults injected in the emulator must stop the acquisition with a
clear error, keep the frames taken so far, and let ``resume`` finish the dataset.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomllib
from conftest import start_emulate_cli

from selfcal.acquisition.acquire import AcquisitionError
from selfcal.acquisition.emulator_backend import SimEmulatorBackend
from selfcal.acquisition.hardware import hardware_settings, open_hardware_robot
from selfcal.config.scenario import (
    ConfigError,
    default_scenario_path,
    load_scenario,
    scenario_to_dict,
)
from selfcal.hw.acl.errors import AclConnectionError
from selfcal.hw.acl.robot import AclRobot
from selfcal.hw.emulator.faults import Fault
from selfcal.hw.emulator.server import AclEmulator
from selfcal.hw.encoders import EncoderTable
from selfcal.io.calibration import read_calibration
from selfcal.io.dataset import Dataset
from selfcal.kinematics.accuracy import aligned_errors, tool_tips
from selfcal.pipeline.run import run_acquire, run_calibrate
from selfcal.robot.interface import Robot

FAST = 3000.0  # emulated joint speed, deg/s: the moves are not what is tested here
FAULT_SECTIONS = {"trajectory": {"poses": 12}}
FAULT_FRAME = 5  # the fault hits while frame 5 (0-based) is being taken


def scenario_file(path: Path, snippet: str, extra: str = "") -> Path:
    """``scenarios/paper.toml`` with ``backend = "hardware"`` and the emulator's table appended."""
    text = default_scenario_path().read_text()
    assert 'backend = "sim"' in text
    path.write_text(
        text.replace('backend = "sim"', 'backend = "hardware"') + "\n" + snippet + extra
    )
    return path


def truth_errors(root: Path, truth, q_rad: np.ndarray) -> dict:
    """Tool-tip errors (mm, after rigid alignment) of the calibrated and nominal models at ``q``."""
    est = read_calibration(root).model
    p_true = tool_tips(truth.true_model, q_rad, truth.T_cam_tip)
    return {
        "calibrated": aligned_errors(tool_tips(est, q_rad, truth.T_cam_tip), p_true)["rms"],
        "nominal": aligned_errors(tool_tips(truth.nominal_model, q_rad, truth.T_cam_tip), p_true)[
            "rms"
        ],
    }


@pytest.fixture(scope="module")
def backend():
    """The default scenario's simulated robot (every scenario here shares its robot and field)."""
    b = SimEmulatorBackend.from_scenario(load_scenario(), seed=1)
    yield b
    b.close()


@pytest.fixture(scope="module")
def runs(shared, backend):
    """The default scenario acquired and calibrated through the hardware path and the sim backend,
    once per test run (shared in tests/conftest.py; the first worker's ``backend`` moves): read
    the datasets, never write into them."""

    def build(tmp: Path) -> dict:
        f = tmp / "f"
        with AclEmulator(backend, move_speed_deg_s=FAST, tcp_port=None, frames_dir=f) as emu:
            s_hw = load_scenario(scenario_file(tmp / "hw.toml", emu.hardware_snippet()))
            assert s_hw.robot.backend == "hardware" and s_hw.robot.hardware.port == emu.pty_path
            t0 = time.perf_counter()
            run_acquire(s_hw, tmp / "hw", quiet=True)
            t_acq = time.perf_counter() - t0
            rests = list(backend.rests)
        doc_hw = run_calibrate(tmp / "hw", quiet=True)
        s_sim = load_scenario()
        run_acquire(s_sim, tmp / "sim", quiet=True)
        doc_sim = run_calibrate(tmp / "sim", quiet=True)
        return {
            "s_hw": s_hw,
            "s_sim": s_sim,
            "hw": tmp / "hw",
            "sim": tmp / "sim",
            "doc_hw": doc_hw,
            "doc_sim": doc_sim,
            "rests": rests,
            "t_acq": t_acq,
        }

    return shared("hardware-e2e-runs", build)


@pytest.mark.slow
def test_same_scenario_but_the_flag(runs):
    a, b = scenario_to_dict(runs["s_hw"]), scenario_to_dict(runs["s_sim"])
    assert a["robot"]["backend"] == "hardware" and b["robot"]["backend"] == "sim"
    a.pop("robot"), b.pop("robot")
    assert a == b


@pytest.mark.slow
def test_hardware_dataset_has_the_sim_format_and_no_truth(runs):
    hw, sim = runs["hw"], runs["sim"]
    assert not (hw / "truth.json").exists() and (sim / "truth.json").exists()
    names = lambda root: sorted(  # noqa: E731
        str(p.relative_to(root)) for p in root.rglob("*") if p.name != "truth.json"
    )
    assert names(hw) == names(sim)
    info_hw = json.loads((hw / "dataset.json").read_text())
    info_sim = json.loads((sim / "dataset.json").read_text())
    assert info_hw.keys() == info_sim.keys()
    assert info_hw["backend"] == "hardware" and info_hw["observation"] == "images"
    assert (hw / "joints.csv").read_text().splitlines()[0] == (
        (sim / "joints.csv").read_text().splitlines()[0]
    )
    img = cv2.imread(str(hw / "frames" / "0000_left.png"))
    assert img.shape == (480, 640, 3) and img.std() > 10  # a rendered scene, not a blank frame


@pytest.mark.slow
def test_joints_are_the_encoder_readings_of_where_the_arm_rests(runs, backend):
    """joints.csv = the commanded targets in counts, read back; the simulated arm rests within
    the encoder resolution of them (so the dataset's joints carry real quantisation only)."""
    ds = Dataset.open(runs["hw"])
    enc = backend.encoders
    plan = ds.info.planned_joints_deg
    np.testing.assert_allclose(ds.joints_deg, enc.to_degrees(enc.to_counts(plan)), atol=2e-6)
    rests = runs["rests"][-len(plan) :]  # one rest per move; the first was the start
    true = np.array([r["true_deg"] for r in rests])
    err = np.abs(true - ds.joints_deg)
    assert np.all(err <= enc.resolution_deg + 2e-6), err.max(0)
    assert np.all(err.max(0) > enc.resolution_deg * 0.2)  # and the jitter is really there


@pytest.mark.slow
def test_calibrated_model_against_truth_and_the_sim_backend(runs, backend):
    """Calibrated tool-tip error of the hardware path within 1.5x the sim backend's on the same
    scenario, both measured on the union of the two datasets' validation postures (40, never
    acquired) against the simulator's truth."""
    truth = backend.truth()
    qv = np.radians(
        np.concatenate(
            [
                Dataset.open(runs["hw"]).info.validation_joints_deg,
                Dataset.open(runs["sim"]).info.validation_joints_deg,
            ]
        )
    )
    e_hw = truth_errors(runs["hw"], truth, qv)
    e_sim = truth_errors(runs["sim"], truth, qv)
    print(
        f"tool-tip RMS over {len(qv)} validation postures: nominal {e_hw['nominal']:.4f} mm, "
        f"calibrated hardware path {e_hw['calibrated']:.4f} mm, sim backend "
        f"{e_sim['calibrated']:.4f} mm (ratio {e_hw['calibrated'] / e_sim['calibrated']:.2f}); "
        f"hardware acquisition of {len(runs['rests']) - 1} frames {runs['t_acq']:.1f} s"
    )
    assert e_hw["calibrated"] <= 1.5 * e_sim["calibrated"]
    assert e_hw["calibrated"] * 5 <= e_hw["nominal"]
    fx = runs["doc_hw"].intrinsics.fx
    assert abs(fx / truth.intrinsics_left.fx - 1) < 0.005


# ---- faults during acquisition ---------------------------------------------------------------


def _emulator(backend, tmp: Path) -> AclEmulator:
    return AclEmulator(
        backend,
        move_speed_deg_s=FAST,
        tcp_port=None,
        frames_dir=tmp / "frames",
        pty_link=tmp / "scorbot-tty",
    ).start()


def _fault_scenario(tmp: Path, emu: AclEmulator):
    # the link's default reply deadline (2 s): with 0.5 s the abort's CLRBUF prompt came too late
    # on loaded cores and the timeout fault's "abort sequence sent" was lost (slow tier, load ~20)
    extra = "\n[robot.hardware.options]\nquery_timeout_s = 2.0\npoll_interval_s = 0.01\n"
    return load_scenario(
        scenario_file(tmp / "hw.toml", emu.hardware_snippet(), extra), overrides=FAULT_SECTIONS
    )


def _abort_after_fault(emu: AclEmulator, n_before: int) -> bool:
    rest = emu.commands[n_before:]
    return "^A" in rest and "CLRBUF" in rest[rest.index("^A") + 1 :]


K = FAULT_FRAME
FAULTS = {
    "timeout": (Fault("timeout", on="MOVE", skip=K), "no prompt from the controller", True),
    # a single garbled reply is retried: this one persists over the query's 3 attempts
    "garble": (Fault("garble", on="LISTPV", skip=2 * K, count=3), "garbled reply", True),
    "impact": (
        Fault("impact", on="MOVE", skip=K, axis=2, at_fraction=0.3),
        "IMPACT PROTECTION axis 2",
        True,
    ),
    "disconnect": (Fault("disconnect", on="MOVE", skip=K, after_s=0.0), "link lost", False),
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(FAULTS))
def test_fault_stops_cleanly_and_resume_completes(kind, tmp_path, backend):
    fault, cause, link_alive = FAULTS[kind]
    out = tmp_path / "ds"
    emu = _emulator(backend, tmp_path)
    try:
        s = _fault_scenario(tmp_path, emu)
        assert s.robot.hardware.port == str(tmp_path / "scorbot-tty")
        emu.inject_fault(fault)
        with pytest.raises(AcquisitionError) as ei:
            run_acquire(s, out, quiet=True)
        msg = str(ei.value)
        assert f"stopped at frame {K} of 12" in msg and cause in msg, msg
        assert "--resume" in msg
        if link_alive:
            assert "abort sequence (Ctrl-A, CLRBUF) sent" in msg, msg
            first = next(i for i, c in enumerate(emu.commands) if c.startswith("DEFP"))
            assert _abort_after_fault(emu, first)
        else:
            assert "could not be delivered" in msg and "emergency stop" in msg, msg
            assert emu.disconnected and not (tmp_path / "scorbot-tty").exists()
        # the frames taken before the fault are intact, nothing of the failed one
        ds = Dataset.open(out)
        assert ds.indices.tolist() == list(range(K))
        assert len(list((out / "frames").glob("*.png"))) == 2 * K
        assert not (out / "truth.json").exists()
        # a healthy controller: the same one with the fault gone, or a fresh one after the
        # disconnect (same port name through the link, same frame folder)
        if link_alive:
            emu.clear_faults()
        else:
            emu.stop()
            emu = _emulator(backend, tmp_path)
        n = len(backend.rests)
        run_acquire(s, out, resume=True, quiet=True)
        assert len(backend.rests) - n == 12 - K  # only the missing frames were taken
    finally:
        emu.stop()
    ds = Dataset.open(out)
    assert ds.indices.tolist() == list(range(12))
    run_calibrate(out, quiet=True)
    e = truth_errors(out, backend.truth(), np.radians(ds.info.validation_joints_deg))
    assert e["calibrated"] * 3 <= e["nominal"], e


def test_encoder_table_of_a_model():
    """``for_robot``: the vendor table (docs/hardware.md) for er4u-vendor; for er4u-paper zero at
    the TOML home, the differential wrist at one resolution (55.8 counts per degree of pitch and
    of roll, i.e. 27.9 per motor)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vendor = EncoderTable.for_robot("er4u-vendor")
    per_90 = np.array([-12770, -10216, 10216, 2511, 2511])
    np.testing.assert_allclose(vendor.counts_per_deg * 90, per_90, rtol=1e-12)
    np.testing.assert_array_equal(vendor.home_deg, [0.0, 120.28, -95.02, -88.81, 0.0])
    assert vendor.differential == (3, 4)
    np.testing.assert_allclose(vendor.resolution_deg[3:], 1 / 55.8)
    paper = EncoderTable.for_robot("er4u-paper")
    home = np.array([38.15, -30.0, 45.0, -63.54, 0.0])
    np.testing.assert_array_equal(paper.to_counts(home), np.zeros(5))
    np.testing.assert_array_equal(paper.to_counts(home + [0, 0, 0, 1, 1]), [0, 0, 0, 56, 0])


# ---- safety and configuration errors ---------------------------------------------------------


def test_out_of_range_command_refused_before_any_byte(tmp_path, backend):
    emu = _emulator(backend, tmp_path)
    try:
        s = _fault_scenario(tmp_path, emu)
        robot = open_hardware_robot(s)
        try:
            assert isinstance(robot, Robot) and robot.model_name == "er4u-paper"
            home = robot.joints()
            np.testing.assert_allclose(home, np.degrees(backend.robot.home), atol=1e-6)
            n_tx, n_rx = len(robot.link.tx_log), len(emu.received)
            q = home.copy()
            q[1] = 131.0  # er4u-paper shoulder range [-35, 130] deg
            with pytest.raises(ValueError, match=r"joint 2 \(shoulder\) = 131.000 deg"):
                robot.move_to(q)
            time.sleep(0.05)
            assert len(robot.link.tx_log) == n_tx and len(emu.received) == n_rx
        finally:
            robot.close()
    finally:
        emu.stop()


def test_open_hardware_robot_errors(tmp_path):
    def scen(**hw):
        return load_scenario(overrides={"robot": {"backend": "hardware", "hardware": hw}})

    no_table = pytest.warns(UserWarning, match="no encoders table")
    with no_table, pytest.raises(AclConnectionError, match=r"'/dev/nonexistent-tty'.*USB-RS-232"):
        open_hardware_robot(scen(port="/dev/nonexistent-tty"))
    with no_table, pytest.raises(AclConnectionError, match=r"socket://127.0.0.1:9.*listening"):
        open_hardware_robot(scen(port="socket://127.0.0.1:9"))
    with pytest.raises(ConfigError, match=r"options.*\['port'\].*directly"):
        open_hardware_robot(scen(options={"port": "loop://"}))
    with pytest.raises(ConfigError, match="camera_size"):
        open_hardware_robot(scen(options={"camera_size": [320, 240]}))
    with pytest.raises(ConfigError, match="unknown"):
        open_hardware_robot(scen(options={"query_timeout": 1.0}))


def test_selfcal_emulate_with_a_scenario(tmp_path):
    """`selfcal emulate SCENARIO` serves the scenario's simulated robot and prints a table that
    connects to it."""
    cfg = tmp_path / "scenario.toml"
    cfg.write_text('[robot]\nmodel = "er4u-paper"\n[trajectory]\nposes = 12\n')
    th, stop, buf, rc = start_emulate_cli([str(cfg), "--frames-dir", str(tmp_path / "frames")], 30)
    try:
        text = buf.getvalue()
        assert "simulated robot of the scenario (er4u-paper)" in text
        pty = next(x.split(": ", 1)[1] for x in text.splitlines() if x.startswith("pty: "))
        assert next(x for x in text.splitlines() if x.startswith("tcp: socket://127.0.0.1:"))
        snippet = text[text.index("[robot.hardware]") : text.index("Ctrl-C")]
        table = tomllib.loads(snippet)["robot"]["hardware"]
        assert table["port"] == pty and len(table["cameras"]) == 2
        with AclRobot.from_settings(
            hardware_settings({"robot": {"model": "er4u-paper", "hardware": table}})
        ) as r:
            r.move_to(np.array([30.0, -20.0, 50.0, -60.0, 10.0]))
            np.testing.assert_allclose(r.joints(), [30, -20, 50, -60, 10], atol=0.02)
            pair = r.capture()
            assert pair.left.shape == (480, 640, 3) and pair.left.std() > 10
    finally:
        stop.set()
        th.join(timeout=10)
    assert rc == [0] and "emulator stopped" in buf.getvalue()
