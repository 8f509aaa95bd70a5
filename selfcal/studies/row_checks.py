"""The reliability checks of a calibration in the rows of studies and Monte Carlo runs.

A calibration can finish and still fail the checks of :mod:`selfcal.calibration.field.quality` (swapped cameras, a
fit worse than the nominal model): ``selfcal calibrate`` then says FAILED and ``calibration.json``
records ``"status": "failed"`` with the failures. A study row (``runs.csv``) and a Monte Carlo
row (``draws.jsonl``, ``runs.csv``) record the same: ``checks`` and ``failed_checks``
(:func:`check_fields`); the summaries count the rows that failed (:func:`count_check_failures`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

__all__ = ["CHECK_KEYS", "check_fields", "count_check_failures"]

CHECK_KEYS = ("checks", "failed_checks")
"""The row keys: ``checks`` is ``"passed"`` or ``"failed"`` (absent or empty for a run that did
not finish), ``failed_checks`` the failures, one sentence each, joined by `` | ``."""


def check_fields(failures: Iterable[str]) -> dict:
    """The row fields of a calibration's check ``failures`` (``CalibrationResult.failures``):
    ``{"checks": "passed" | "failed", "failed_checks": "a | b" or None}``."""
    failures = list(failures)
    return {
        "checks": "failed" if failures else "passed",
        "failed_checks": " | ".join(failures) if failures else None,
    }


def count_check_failures(rows: Iterable[Mapping]) -> int:
    """How many ``rows`` (study or Monte Carlo rows) failed the calibration's checks."""
    return sum(r.get("checks") == "failed" for r in rows)
