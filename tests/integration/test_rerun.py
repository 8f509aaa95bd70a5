"""``selfcal record``: a finished run recorded into a Rerun file that the Rerun CLI can load.

A 10-pose rendered run (images, so the recording holds images and detected corners) is recorded
post hoc and must pass ``rerun rrd verify`` (the CLI shipped with rerun-sdk). Skipped only when
the ``rerun`` executable is missing from the environment. The recording holds one camera entity
per camera of the rig: both of the stereo pair, and the one of ``scenarios/mono.toml`` (read back
with rerun-sdk's ``RrdReader``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from selfcal.cli.main import main
from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire, run_calibrate
from selfcal.plots import rerun_log

REPO = Path(__file__).resolve().parents[2]


def _camera_entities(rrd: Path) -> dict[str, set[str]]:
    """The camera entities of the recording in ``rrd`` by kind (``estimate``, ``truth``): the
    names after ``cam_`` of the entity paths ``/world/<kind>/cam_<name>``."""
    from rerun.chunk import RrdReader

    out: dict[str, set[str]] = {"estimate": set(), "truth": set()}
    for chunk in RrdReader(rrd).stream().to_chunks():
        parts = str(chunk.entity_path).strip("/").split("/")
        if len(parts) >= 3 and parts[0] == "world" and parts[2].startswith("cam_"):
            out.setdefault(parts[1], set()).add(parts[2][4:])
    return out


def _rerun_exe() -> str | None:
    local = Path(sys.executable).with_name("rerun")
    return str(local) if local.is_file() else shutil.which("rerun")


@pytest.fixture(scope="module")
def small_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run") / "ds"
    s = load_scenario(None, {"trajectory": {"poses": 10}, "validation": {"poses": 5}})
    run_acquire(s, out, quiet=True)
    run_calibrate(out, quiet=True)
    return out


@pytest.mark.slow  # the recording of 15 rendered postures and `rerun rrd verify`: over 2 s
def test_record_passes_rrd_verify(small_run, tmp_path):
    exe = _rerun_exe()
    if exe is None:
        pytest.skip("the rerun CLI (shipped with rerun-sdk) is not installed in this environment")
    rrd = tmp_path / "run.rrd"
    parser = argparse.ArgumentParser()
    rerun_log.register(parser.add_subparsers())
    args = parser.parse_args(["record", str(small_run), "--rrd", str(rrd)])
    assert args.func(args) == 0
    assert rrd.stat().st_size > 100_000  # images are in it
    res = subprocess.run(
        [exe, "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "verified without error" in (res.stdout + res.stderr)
    assert _camera_entities(rrd) == {"estimate": {"left", "right"}, "truth": {"left", "right"}}


@pytest.mark.slow  # default tier budget (~90 s): 2-5 s each
def test_one_camera_run_records_one_camera_entity(tmp_path):
    """`selfcal run scenarios/mono.toml --rrd X.rrd` (its camera and lens; the analytic path and
    fewer poses here, for time) writes the recording with one camera, not a right one."""
    toml = tmp_path / "mono.toml"
    toml.write_text((REPO / "scenarios" / "mono.toml").read_text() + "\n[noise]\nrender = false\n"
                    "\n[trajectory]\nposes = 16\n\n[validation]\nposes = 5\n")  # fmt: skip
    rrd = tmp_path / "mono.rrd"
    assert main(["run", str(toml), "--out", str(tmp_path / "run"), "--rrd", str(rrd)]) == 0
    assert rrd.stat().st_size > 10_000
    assert _camera_entities(rrd) == {"estimate": {"left"}, "truth": {"left"}}


@pytest.mark.slow  # default tier budget (~90 s): ~4 s
def test_board_run_records_its_cameras_and_the_board(tmp_path):
    """`selfcal run scenarios/mono-charuco.toml --rrd X.rrd` (the analytic path, fewer poses):
    the recording of the board route holds the board's points and outline, one estimated and
    one true camera entity (its features under the estimate), the robot and the errors."""
    from rerun.chunk import RrdReader

    text = (REPO / "scenarios" / "mono-charuco.toml").read_text()
    toml = tmp_path / "mono-charuco.toml"
    text = text.replace("../models/", f"{REPO}/models/")
    text = text.replace("[trajectory]\n", "[trajectory]\nposes = 15\n")
    toml.write_text(text + "\n[validation]\nposes = 5\n\n[noise]\nrender = false\n")
    rrd = tmp_path / "board.rrd"
    assert main(["run", str(toml), "--out", str(tmp_path / "run"), "--rrd", str(rrd)]) == 0
    assert _camera_entities(rrd) == {"estimate": {"left"}, "truth": {"left"}}
    paths = {str(c.entity_path) for c in RrdReader(rrd).stream().to_chunks()}
    for p in (
        "/world/board/points",
        "/world/board/outline",
        "/world/estimate/cam_left/image/corners",
        "/errors/camera_vs_truth/position_mm",
        "/errors/reprojection_rms_px",
    ):
        assert p in paths, (p, sorted(paths))
    assert any(p.startswith("/world/robot/") for p in paths)


def test_record_needs_a_calibration(default_analytic, tmp_path):
    from selfcal.io.dataset import DatasetError

    # acquired, not calibrated: a copy of the shared analytic run without its calibration.json
    # (the refusal needs no images; acquiring a run of its own cost 1.3 CPU s)
    ds = shutil.copytree(default_analytic[0], tmp_path / "ds")
    (ds / "calibration.json").unlink()
    with pytest.raises(DatasetError, match="calibrate"):
        rerun_log.record_run(ds, tmp_path / "x.rrd")


def test_record_shows_its_progress_on_a_terminal(default_analytic, tmp_path, monkeypatch):
    """`selfcal record` (3.4 s) showed nothing on a terminal until it ended. (The default
    scenario's analytic run, shared with other tests: recorded to a file outside its folder.)"""
    import io
    import re

    small_run = default_analytic[0]

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    tty = Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    assert main(["record", str(small_run), "--rrd", str(tmp_path / "run.rrd")]) == 0
    monkeypatch.undo()
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", tty.getvalue())
    assert f"recording {small_run} ..." in text  # the spinner while it runs
    assert re.search(rf"recording {re.escape(str(small_run))}: .*run\.rrd \(\d+\.\d s\)", text)
