"""Helpers of the dataset tests (#15): a small analytic dataset and the CLI run in-process."""

from __future__ import annotations

from pathlib import Path

from scenarios import cli
from scenarios.config import load_scenario
from scenarios.pipeline import run_acquire


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
