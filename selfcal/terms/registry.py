"""The measurement kinds this version knows: each a :class:`selfcal.terms.base.Term` and the type
of its ``calibration.json`` section.

Adding a kind is one module under :mod:`selfcal.terms` (its data, residual and parameter blocks,
report and section) and one line in :data:`KINDS` (docs/terms.md). The estimators never look
here: they take the terms they are given; the registry is for reading a ``calibration.json`` with
every kind's section checked as its type (:func:`read_calibration`) and for listing the kinds.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from selfcal.io.calibration import CalibrationResult
from selfcal.io.calibration import read_calibration as _read_calibration
from selfcal.io.calibration_terms import SectionType
from selfcal.io.calibration_tracker import TrackerSource
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.terms.tracker import TrackerTerm

__all__ = ["TermKind", "KINDS", "section_types", "read_calibration"]


@dataclass(frozen=True)
class TermKind:
    """A registered kind: its ``name`` (the section's key in ``calibration.json``), its term
    class and its section type."""

    name: str
    term: type
    section: SectionType


KINDS: tuple[TermKind, ...] = (
    TermKind("tracker", TrackerTerm, TrackerSource),
    TermKind("probe", ProbeTerm, ProbeSection),
    # one line per kind
)


def section_types() -> dict[str, SectionType]:
    """Every registered kind's section type, by name."""
    return {k.name: k.section for k in KINDS}


def read_calibration(path: str | Path) -> CalibrationResult:
    """:func:`selfcal.io.calibration.read_calibration` with every registered kind's section read
    and checked as its type (the raises of that function)."""
    return _read_calibration(path, section_types())
