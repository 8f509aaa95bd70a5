"""Every calibration stage shows up on a terminal with its cost (#16 item 3): detection as a bar,
then the camera stage, the identification, the one-step refinement, the bounds and the fair
nominal as steps."""

from __future__ import annotations

import io
import re

import pytest

from selfcal.calibration.field.calibrate import calibrate
from selfcal.config.scenario import load_scenario
from selfcal.console.progress import Progress
from selfcal.pipeline.run import run_acquire


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_each_stage_with_its_cost(tmp_path):
    s = load_scenario(
        overrides={
            "noise": {"render": False},
            "trajectory": {"poses": 8},
            "validation": {"poses": 3},
        }
    )
    run_acquire(s, tmp_path / "ds", quiet=True)
    tty = Tty()
    res = calibrate(tmp_path / "ds", progress=Progress("detect", stream=tty))
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", tty.getvalue())  # rich's colours and cursor
    lines = [seg for seg in re.split(r"[\r\n]", text) if seg.strip()]
    done = [ln for ln in lines if not ln.endswith(" ...")]
    names = [ln.split(":")[0] for ln in done]
    assert names == [
        "camera stage (bundle adjustment)",
        "kinematic identification",
        "one-step refinement (all images)",
        "Cramer-Rao bounds",
        "fair nominal (the nominal chain fitted to the same pixels)",
    ]
    assert f"reprojection RMS {res.methods['two-stage'].reprojection_rms_px:.3f} px" in done[0]
    assert re.search(
        r"tool RMS \d+\.\d{3} mm / \d+\.\d{4} deg, rank \d+/\d+ \(\d+\.\d s\)", done[1]
    )
    assert f"reprojection RMS {res.reprojection_rms_px:.3f} px" in done[2]
    assert res.nominal is not None  # the reference the calibration is judged against
    rms = res.nominal.calibration_images_rms_px["nominal"]
    assert f"predicts the calibration images with {rms:.3f} px RMS" in done[4]


class _Count:
    """A progress that records its total and its steps."""

    def __init__(self) -> None:
        self.total, self.steps, self.finished = None, 0, False

    def start(self, total: int) -> None:
        self.total = total

    def advance(self) -> None:
        self.steps += 1

    def finish(self) -> None:
        self.finished = True


@pytest.mark.slow  # default tier budget (~90 s): 2-5 s each
def test_detection_counts_one_image_per_camera(tmp_path):
    """A one-camera dataset's detection bar runs to its image count (it said 30/60 for
    scenarios/mono.toml: the total assumed two cameras)."""
    from pathlib import Path

    from selfcal.calibration.field.calibrate import detect_dataset
    from selfcal.io.dataset import Dataset

    mono = Path(__file__).resolve().parents[2] / "scenarios" / "mono.toml"
    s = load_scenario(mono, overrides={"trajectory": {"poses": 8}, "validation": {"poses": 3}})
    run_acquire(s, tmp_path / "ds", quiet=True)
    ds = Dataset.open(tmp_path / "ds")
    bar = _Count()
    detect_dataset(ds, progress=bar)
    assert ds.info.cameras == ("left",)
    assert bar.total == bar.steps == len(list(ds.image_paths())) == 8 and bar.finished


def _shown(tty: Tty) -> list[str]:
    """The lines a terminal kept (rich's colours and cursor moves dropped)."""
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", tty.getvalue())
    return [seg for seg in re.split(r"[\r\n]", text) if seg.strip()]


@pytest.mark.slow  # a board calibration and its report with figures: ~3 s
def test_board_calibrate_and_report_show_their_progress(tmp_path, monkeypatch):
    """`selfcal calibrate` of a board dataset (6.5 s) and `selfcal report` (4.5 s) showed
    nothing on a terminal until they ended."""
    import sys
    from pathlib import Path

    from selfcal.cli.main import main

    board = Path(__file__).resolve().parents[2] / "scenarios" / "mono-charuco.toml"
    s = load_scenario(board, {"noise": {"render": False}, "trajectory": {"poses": 12}})
    run_acquire(s, tmp_path / "ds", quiet=True)
    for argv, line in (
        (["calibrate", str(tmp_path / "ds")],
         r"board calibration \(detection, .*\): reprojection RMS \d\.\d{3} px \(\d+\.\d s\)"),
        (["report", str(tmp_path / "ds")], r"report \(validation, figures\): ok \(\d+\.\d s\)"),
    ):  # fmt: skip
        tty = Tty()
        monkeypatch.setattr(sys, "stderr", tty)
        assert main(argv) == 0
        monkeypatch.undo()
        shown = _shown(tty)
        assert any(ln.endswith(" ...") for ln in shown), shown  # the spinner while it runs
        assert any(re.fullmatch(line, ln) for ln in shown), shown


def test_the_report_of_own_data_does_not_say_validation(tmp_path):
    """`selfcal report` of a user's own data labelled its progress "report (validation,
    figures)", though there is no validation against a truth there (new user's trip): the
    label says its held-out check; a simulated dataset keeps "validation"."""
    from selfcal.cli.main import report_label

    assert report_label(tmp_path) == "report (held-out check, figures)"
    (tmp_path / "truth.json").write_text("{}")
    assert report_label(tmp_path) == "report (validation, figures)"
