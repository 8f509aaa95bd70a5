"""The field route's errors: a dataset that cannot be calibrated (:class:`CalibrationError`) and
a calibration that ran to the end but failed its checks (:class:`CalibrationFailedError`); and
the fewest postures it calibrates from (:data:`MIN_POSTURES`, which a scenario's range names
without importing the calibration)."""

from __future__ import annotations

from pathlib import Path

from selfcal.errors import EstimationError

__all__ = ["CalibrationError", "CalibrationFailedError", "MIN_POSTURES"]

MIN_POSTURES = 6
"""Postures (with markers seen) a field calibration needs at the least."""


class CalibrationError(EstimationError, ValueError):
    """The dataset cannot be calibrated; the message names the cause and the fix. (Still a
    ``ValueError``, as it always was.)"""


class CalibrationFailedError(CalibrationError):
    """A calibration that ran to the end but failed a check of :mod:`selfcal.calibration.field.quality` (worse
    than the nominal model, swapped cameras): the message lists the failures and their likely
    causes; the result is written all the same, marked ``"status": "failed"``."""

    @classmethod
    def of(cls, failures: tuple[str, ...], where: str | Path) -> CalibrationFailedError:
        """The error for the ``failures`` of the calibration written to ``where``."""
        lines = "".join(f"\n  - {f}" for f in failures)
        return cls(
            f"the calibration FAILED {len(failures)} check(s) and is marked failed in {where} "
            f'("status": "failed"):{lines}',
            fix="remove the cause named above and calibrate again; do not use this calibration",
        )
