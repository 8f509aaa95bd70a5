"""The measurement kinds this version knows: each a :class:`selfcal.terms.base.Term` and the type
of its ``calibration.json`` section.

Adding a kind is one module under :mod:`selfcal.terms` (its data, residual and parameter blocks,
report and section; its file reader ``from_file`` and its options ``OPTIONS``) and one line in
:data:`KINDS` (docs/terms.md). The estimators never look here: they take the terms they are
given; the registry is for reading a ``calibration.json`` with every kind's section checked as
its type (:func:`read_calibration`, :func:`read_board_calibration`), for listing the kinds and
for making a term from the command line's ``--term KIND=FILE[,NAME=VALUE ...]``
(:func:`term_from_spec`: any registered kind, its options checked by their declaration).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from selfcal.errors import InputError
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.board_calibration import read_board_calibration as _read_board
from selfcal.io.calibration import CalibrationResult
from selfcal.io.calibration import read_calibration as _read_calibration
from selfcal.io.calibration_terms import SectionType
from selfcal.io.calibration_tracker import TrackerSource
from selfcal.robot.definition import RobotDef
from selfcal.terms.base import Term, TermOption
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.terms.tracker import TrackerTerm

__all__ = [
    "TermKind",
    "KINDS",
    "TermSpec",
    "kinds_help",
    "parse_term_spec",
    "section_types",
    "read_board_calibration",
    "read_calibration",
    "term_from_spec",
]


@dataclass(frozen=True)
class TermKind:
    """A registered kind: its ``name`` (the section's key in ``calibration.json``), its term
    class (with ``OPTIONS``, :class:`selfcal.terms.base.TermOption`, and ``from_file(path, robot,
    options)``) and its section type."""

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


def read_board_calibration(path: str | Path) -> BoardCalibrationResult:
    """:func:`selfcal.io.board_calibration.read_board_calibration` with every registered kind's
    section read and checked as its type (the raises of that function)."""
    return _read_board(path, section_types())


@dataclass(frozen=True)
class TermSpec:
    """``--term KIND=FILE[,NAME=VALUE ...]`` split: the ``kind``, the ``file`` and the options
    as written (``values``), ``text`` the whole for messages."""

    kind: TermKind
    file: str
    values: dict[str, str]
    text: str

    def options(self, defaults: Mapping[str, str | None] = {}) -> dict[str, Any]:
        """Every option of the kind parsed: as given, else ``defaults`` (the command's, e.g.
        ``--joint-units``), else the option's own default; an optional one without either is
        None.

        Raises:
            InputError: a value an option does not take, or a required option missing (named
                with the fix).
        """
        out: dict[str, Any] = {}
        where = f"--term {self.text}"
        for opt in _options(self.kind):
            text = self.values.get(opt.name) or defaults.get(opt.name) or opt.default
            if text is None:
                if opt.required:
                    raise InputError(f"{where}: {self.kind.name} needs {opt.name}",
                                     fix=f"add ,{opt.name}=VALUE ({opt.describe()})")  # fmt: skip
                out[opt.name] = None
                continue
            out[opt.name] = opt.parse(text, where)
        return out


def _options(kind: TermKind) -> tuple[TermOption, ...]:
    return tuple(getattr(kind.term, "OPTIONS", ()))


def kinds_help() -> str:
    """Every registered kind with its options (name, unit, default, what), one line each."""
    return "; ".join(
        f"{k.name}=FILE" + "".join(f", {o.describe()}" for o in _options(k)) for k in KINDS
    )


def parse_term_spec(text: str) -> TermSpec:
    """``KIND=FILE[,NAME=VALUE ...]`` (a file name with a comma cannot be given this way).

    Raises:
        InputError: no ``KIND=FILE``, a kind not registered, an option the kind does not have,
            or an option given twice (each named, with the kinds or options there are).
    """
    where = f"--term {text}"
    head, *rest = text.split(",")
    kind_name, eq, file = head.partition("=")
    if not eq or not kind_name.strip() or not file.strip():
        raise InputError(f"{where}: give a kind and its file as KIND=FILE",
                         fix=f"e.g. --term probe=touches.csv,sigma_mm=0.02 (kinds: "
                         f"{', '.join(k.name for k in KINDS)}; docs/terms.md)")  # fmt: skip
    by_name = {k.name: k for k in KINDS}
    kind = by_name.get(kind_name.strip())
    if kind is None:
        raise InputError(f"{where}: no measurement kind {kind_name.strip()!r}",
                         fix=f"give one of {', '.join(by_name)} (docs/terms.md)")  # fmt: skip
    names = {o.name for o in _options(kind)}
    values: dict[str, str] = {}
    for item in rest:
        name, eq, value = (p.strip() for p in item.partition("="))
        if name not in names or not eq or not value:
            known = "; ".join(o.describe() for o in _options(kind)) or "none"
            raise InputError(f"{where}: {item.strip()!r} is no option NAME=VALUE of {kind.name}",
                             fix=f"its options: {known}")  # fmt: skip
        if name in values:
            raise InputError(f"{where}: {name} is given twice", fix=f"give {name} once")
        values[name] = value
    return TermSpec(kind, file.strip(), values, text)


def term_from_spec(text: str, robot: RobotDef, defaults: Mapping[str, str | None] = {}) -> Term:
    """The term of ``--term KIND=FILE[,NAME=VALUE ...]`` for ``robot``: its kind's
    ``from_file`` with the options parsed (:meth:`TermSpec.options`; ``defaults`` the command's).

    Raises:
        InputError: a bad spec (:func:`parse_term_spec`, :meth:`TermSpec.options`), a missing
            file, or a file that cannot be read (named by the kind's reader, with row and
            column).
    """
    spec = parse_term_spec(text)
    options = spec.options(defaults)
    if not Path(spec.file).is_file():
        raise InputError(f"--term {text}: {spec.file} is not a file",
                         fix=f"give the {spec.kind.name} measurements' file (docs/terms.md)")  # fmt: skip
    cls: Any = spec.kind.term  # a term class of KINDS (its from_file: TermKind's docstring)
    term: Term = cls.from_file(spec.file, robot, options)
    return term
