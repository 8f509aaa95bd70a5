"""Helpers of the dataset tests (#15): a small analytic dataset and the CLI run in-process."""

from __future__ import annotations

import json
from pathlib import Path

from selfcal.cli import main as cli
from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire


def run(capsys, *argv) -> tuple[int, str, str]:
    """``selfcal ARGV`` in-process: exit code, stdout, stderr."""
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def acquire_analytic(out: Path, poses: int, validation: int) -> Path:
    """The default scenario on the analytic path (detections, no rendering) with ``poses``
    postures and ``validation`` held-out ones, acquired into ``out``."""
    overrides = {"noise": {"render": False}, "trajectory": {"poses": poses},
                 "validation": {"poses": validation}}  # fmt: skip
    run_acquire(load_scenario(overrides=overrides), out, quiet=True)
    return out


def plan_same_postures(root: Path, rows: list[str]) -> None:
    """Make ``root/dataset.json`` plan the postures of the joints.csv ``rows`` (``index,q...``
    text, in frame order): a test that edits the read-back edits the plan with it, or the
    calibration names the frames whose joints left their planned postures (#15)."""
    doc = json.loads((root / "dataset.json").read_text())
    doc["trajectory_joints_deg"] = [[float(v) for v in r.split(",")[1:]] for r in rows]
    (root / "dataset.json").write_text(json.dumps(doc))
